"""JSON text from one C encoder made once: what every JSON line and MCAP message is written with.

``json.JSONEncoder.encode`` builds a new C encoder (and a Python generator)
on every call, which was a third of what a new frame's JSON line cost in
``hex decode --json`` and half of an MCAP message's; the arguments here are
those ``JSONEncoder.iterencode`` gives it, so the text is exactly
``json.dumps``'s with the same options. Where the C encoder is missing (another
Python), the documented way is used. Standard library only.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any


def json_encoder(*, compact: bool = False, ensure_ascii: bool = False) -> Callable[[Any], str]:
    """``json.dumps(value, ensure_ascii=..., separators=(",", ":") if compact)``, made once."""
    separators = (",", ":") if compact else (", ", ": ")
    plain = json.JSONEncoder(ensure_ascii=ensure_ascii, separators=separators).encode
    make = getattr(json.encoder, "c_make_encoder", None)
    if make is None:
        return plain
    strings = json.encoder.encode_basestring_ascii if ensure_ascii else json.encoder.encode_basestring
    try:  # markers, default, strings, indent, key separator, item separator, sort_keys, skipkeys, allow_nan
        encoder = make(None, _refuse, strings, None, separators[1], separators[0], False, False, True)
    except TypeError:  # another signature: the documented way
        return plain

    def encode(value: Any) -> str:
        return "".join(encoder(value, 0)) if isinstance(value, (dict, list)) else plain(value)

    return encode


def _refuse(value: object) -> object:
    raise TypeError(f"Object of type {type(value).__name__} is not JSON serializable")


def flat_dict_encoder(encode: Callable[[Any], str]) -> Callable[[dict[str, Any]], str]:
    """``encode`` for a message's fields (a dict of numbers and lists of numbers, by name): the same text.

    Numbers are what ``json`` writes them as (an int's ``repr``, a finite
    float's ``repr``), and a list of ints is its own ``str``; each key is
    encoded once. Anything else (text, flags, nesting, NaN) goes to ``encode``.
    For the frames a large capture holds only once, where the C encoder's
    per-call set-up was a third of a new frame's JSON.
    """
    keys: dict[str, str] = {}

    def encode_flat(fields: dict[str, Any]) -> str:
        if len(fields) == 1:  # most messages: one field, and it is a number or a list of ints
            ((name, value),) = fields.items()
            key = keys.get(name)
            kind = type(value)
            if key is not None and (kind is int or (kind is list and set(map(type, value)) <= _INT)):
                return f"{{{key}{value!r}}}"
            return f"{{{item(name, value)}}}"
        parts = []
        for name, value in fields.items():  # several: ints, mostly (a pair of speeds, a broadcast)
            key = keys.get(name)
            parts.append(f"{key}{value!r}" if key is not None and type(value) is int else item(name, value))
        return "{" + ", ".join(parts) + "}"

    def item(name: str, value: Any) -> str:
        key = keys.get(name)
        if key is None:
            key = keys[name] = f"{encode(name)}: "
        kind = type(value)
        if (
            kind is int
            or (kind is float and value - value == 0)  # finite: NaN and infinities are not
            or (kind is list and set(map(type, value)) <= _INT)
        ):
            return f"{key}{value!r}"
        return key + encode(value)

    return encode_flat


_INT = frozenset((int,))
