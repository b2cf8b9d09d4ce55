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
