"""JSON text from one ``json.JSONEncoder`` made once: what every JSON line and MCAP message is written with.

``json.dumps`` with options builds a new ``JSONEncoder`` on every call; this
builds it once, and its ``encode`` gives exactly ``json.dumps``'s text with
the same options. (Its C encoder could be kept too, called as
``JSONEncoder.iterencode`` calls it, but that is ``json``'s private
signature.) Most of the volume does not come here at all: the flat dicts of
a message's fields go through ``flat_dict_encoder``. Standard library only.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any


def json_encoder(*, compact: bool = False, ensure_ascii: bool = False) -> Callable[[Any], str]:
    """``json.dumps(value, ensure_ascii=..., separators=(",", ":") if compact)``, made once."""
    separators = (",", ":") if compact else (", ", ": ")
    return json.JSONEncoder(ensure_ascii=ensure_ascii, separators=separators).encode


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
            if key is not None and (kind is int or (kind is list and _INT.issuperset(map(type, value)))):
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
            or (kind is list and _INT.issuperset(map(type, value)))
        ):
            return f"{key}{value!r}"
        return key + encode(value)

    return encode_flat


def flat_values_encoder(
    encode_flat: Callable[[dict[str, Any]], str], encode: Callable[[Any], str]
) -> Callable[[tuple[str, ...]], Callable[[tuple[Any, ...]], str]]:
    """``encode_flat`` (a ``flat_dict_encoder``) of a message's fields handed as their values, for the
    names given: the same text. Ints, the common case, fill a format made once for the names (an
    int's JSON is its ``repr``, which ``format`` writes); anything else goes to ``encode_flat``."""

    def for_names(names: tuple[str, ...]) -> Callable[[tuple[Any, ...]], str]:
        keys = [_braces(f"{encode(name)}: ") + "{}" for name in names]
        fill = ("{{" + ", ".join(keys) + "}}").format

        def encode_values(values: tuple[Any, ...]) -> str:
            if _INT.issuperset(map(type, values)):
                return fill(*values)
            return encode_flat(dict(zip(names, values, strict=True)))

        return encode_values

    return for_names


def _braces(text: str) -> str:
    """``text`` as a literal part of a format string."""
    return text.replace("{", "{{").replace("}", "}}")


_INT = frozenset((int,))
