"""What every input file is held to, whoever wrote it: a quote of it is short, its nesting shallow.

A file handed to hcrctl (a ``--log``, the config file, a capture) may be
damaged, or made by someone who wants to hurt: a 50 MB value, 100,000 nested
brackets. Two things then go wrong unless checked first: an error message
that quotes the content becomes megabytes of stderr, and a recursive parser
(``json``, ``tomllib``) dies of ``RecursionError`` deep inside. ``quoted``
keeps any quote to about 100 characters; ``too_deep`` measures the nesting
before any parser runs (in C but for the rare text with many brackets), so a
line is refused instead of recursed into.

JSON from a peer (a Foxglove client, a fleet operator, a robot's reply) is
read by ``peer_json`` alone: at most ``MAX_PEER_JSON`` bytes, ``MAX_DEPTH``
deep, no ``NaN`` or ``Infinity``, each checked before the parser runs, so a
hostile message costs a length, two counts and a refusal.

Standard library only: the config reader and the codec's neighbours use it.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from itertools import accumulate, islice

from .errors.terminal import quoted as quoted  # re-exported: where a reader of input files finds it

#: The deepest nesting of arrays and objects (or inline tables) a file may use: the files hcrctl
#: writes and reads go three deep, and a parser that recurses must never get near its limit.
MAX_DEPTH = 16

#: The largest JSON document a peer may send: what a Foxglove client's control message needs (a
#: subscription for each channel, an advertise with its schema) and the WebSocket's own bound on a
#: message; a Twist, a query or an answer is far smaller. Parsing it costs well under a millisecond.
MAX_PEER_JSON = 64 * 1024

#: A JSON string, escapes included (its brackets are text, not structure): a pattern, compiled (and
#: cached by ``re``) only when a text has enough brackets to need it.
JSON_STRINGS = rb'"[^"\\]*(?:\\.[^"\\]*)*"'
#: TOML's four kinds of string, and comments, whose brackets are text too.
TOML_STRINGS = (
    rb'"""(?:[^\\]|\\[\s\S])*?"""'
    rb"|'''[\s\S]*?'''"
    rb'|"[^"\\\n]*(?:\\.[^"\\\n]*)*"'
    rb"|'[^'\n]*'"
    rb"|#[^\n]*"
)
_NOT_BRACKETS = bytes(b for b in range(256) if b not in b"[]{}")
_BRACKETS = rb"[\[\]{}]"
_STEP = {ord("["): 1, ord("{"): 1, ord("]"): -1, ord("}"): -1}


def blanked(raw: bytes, strings: bytes) -> bytes:
    """``raw`` with each match of the pattern ``strings`` (strings, comments) overwritten by as many
    ``s``: what is left is structure, and every offset still points where it did in ``raw``."""
    return re.sub(strings, lambda m: b"s" * len(m.group()), raw)


def too_deep(raw: bytes, strings: bytes = JSON_STRINGS, limit: int = MAX_DEPTH) -> int:
    """The offset in ``raw`` of the bracket that opens more than ``limit`` arrays or objects inside one
    another; -1 if none does.

    A text with ``limit`` brackets or fewer cannot, and that is every line
    hcrctl writes, so two ``count`` calls decide almost always. Otherwise the
    strings (and comments) are blanked, the brackets kept, and the running sum
    of their steps is the depth a parser would reach at each (an unbalanced
    text counts as deep as it opens). Linear, whatever the text.
    """
    if raw.count(b"[") + raw.count(b"{") <= limit:
        return -1
    structure = blanked(raw, strings)
    steps = map(_STEP.__getitem__, structure.translate(None, _NOT_BRACKETS))
    nth = next((i for i, depth in enumerate(accumulate(steps)) if depth > limit), -1)
    if nth < 0:
        return -1
    return next(islice(re.finditer(_BRACKETS, structure), nth, None)).start()


class PeerJsonError(ValueError):
    """JSON from a peer refused: too long, too deep, not JSON; the message says which, never quoting it."""


def _no_constant(name: str) -> object:
    raise PeerJsonError(f"{name} is not JSON")


def peer_json(data: bytes | str, parse_int: Callable[[str], object] | None = None) -> object:
    """A peer's JSON document, read on the one budget every reader of the network keeps; else PeerJsonError.

    The size and the nesting are measured before parsing (``MAX_PEER_JSON``,
    ``MAX_DEPTH``); ``NaN`` and ``Infinity`` are refused, as JSON does; bytes
    that are not UTF-8 are "not JSON". ``parse_int`` is ``json.loads``' own
    hook, for a reader that bounds its numbers further.
    """
    raw = data.encode("utf-8", "surrogatepass") if isinstance(data, str) else data
    if len(raw) > MAX_PEER_JSON:
        raise PeerJsonError(f"{len(raw):,} bytes: a message is at most {MAX_PEER_JSON:,}")
    if too_deep(raw) >= 0:
        raise PeerJsonError(f"nested in more than {MAX_DEPTH} arrays or objects")
    try:
        return json.loads(data, parse_int=parse_int, parse_constant=_no_constant)
    except PeerJsonError:
        raise
    except (ValueError, RecursionError) as exc:  # UnicodeDecodeError is a ValueError
        raise PeerJsonError(f"not JSON ({type(exc).__name__})") from exc
