"""Completing and checking a frame typed by hand, for ``hex send`` and the shell's raw mode.

A firmware author types the part of a frame they care about (header,
address, length, command, content) and lets the tool do the arithmetic; or
they paste a whole frame from a capture and want to know it is right before
it reaches the robot. So: a missing checksum and end are appended (and the
user is told), a present but wrong one is refused with what it should be
under both rules, and ``force`` sends anything exactly as typed.
"""

from __future__ import annotations

from ..errors import FrameRefused
from ..protocol.frames import CONTENT_AT, HEADER, LENGTH_AT, TERMINATOR, ChecksumRule, checksum
from ..protocol.profiles import DEFAULT, Profile

#: header (2) + address + length + command: where the content starts
HEAD = CONTENT_AT
FORCE_HINT = "--force sends the bytes exactly as typed"


def complete_frame(
    data: bytes, rule: ChecksumRule | str, force: bool = False, profile: Profile = DEFAULT
) -> tuple[bytes, str | None]:
    """The frame to send and a note for the user (None when sent as typed without comment).

    Raises FrameRefused (exit 1) for a wrong checksum, terminator or length
    unless ``force``, in which case the bytes go out as typed and the note
    says what is wrong with them. Under another ``profile`` (v0.11) the frame
    ends in that profile's terminator instead; the checksum is still the
    document's (that firmware ignores it, so hcrctl sends the document's).
    """
    rule = ChecksumRule(rule)
    try:
        if profile.terminator != TERMINATOR:
            return _in_profile(bytes(data), rule, profile)
        return _complete(bytes(data), rule)
    except FrameRefused as exc:
        if not force:
            raise
        return bytes(data), f"sending as typed (--force): {exc.message}"


def _complete(data: bytes, rule: ChecksumRule) -> tuple[bytes, str | None]:
    _check_head(data)
    body = data[: HEAD + data[LENGTH_AT]]
    tail = data[len(body) :]
    if len(tail) == 0:
        ck = checksum(body, rule)
        return body + bytes(
            (ck,)
        ) + TERMINATOR, f"appended checksum {ck:02X} ({_rule_text(rule)}) and end 0D 0A"
    _check_checksum(body, tail[0], rule, maybe_content=len(tail) == 1)
    if len(tail) == 1:
        return data + TERMINATOR, "appended end 0D 0A"
    if tail[1:3] != TERMINATOR[: len(tail) - 1]:
        raise FrameRefused(f"the end is {tail[1:3].hex(' ').upper()}, not 0D 0A", hint=FORCE_HINT)
    if len(tail) == 2:
        return data + TERMINATOR[1:], "appended 0A to complete the end 0D 0A"
    if len(tail) > 3:
        extra = len(tail) - 3
        raise FrameRefused(
            f"{extra} byte{'s' if extra != 1 else ''} after the end 0D 0A; send one frame at a time",
            hint=FORCE_HINT,
        )
    return data, None


def _in_profile(data: bytes, rule: ChecksumRule, profile: Profile) -> tuple[bytes, str | None]:
    """``_complete`` for a profile whose frames end otherwise: typed with that end, or completed to it."""
    whole = len(data) >= HEAD and len(data) == HEAD + data[LENGTH_AT] + 1 + len(profile.terminator)
    if whole and data.endswith(profile.terminator):
        data = data[: -len(profile.terminator)] + TERMINATOR
    frame, note = _complete(data, rule)
    end = profile.terminator.hex(" ").upper()
    return profile.retarget(frame), note and note.replace("0D 0A", end).replace(
        "appended 0A to complete the end", "appended"
    )


def _check_head(data: bytes) -> None:
    if data[:2] != HEADER:
        raise FrameRefused(
            f"a frame starts with 55 AA, not {data[:2].hex(' ').upper() or 'nothing'}", hint=FORCE_HINT
        )
    if len(data) < HEAD:
        raise FrameRefused(
            f"only {len(data)} byte{'s' if len(data) != 1 else ''}: a frame needs at least "
            "55 AA, address, length and command",
            hint=FORCE_HINT,
        )
    have, length = len(data) - HEAD, data[LENGTH_AT]
    if have < length:
        raise FrameRefused(
            f"the length field says {length} content byte{'s' if length != 1 else ''}, "
            f"but {have} stand{'s' if have == 1 else ''} after the command",
            hint=FORCE_HINT,
        )


def _check_checksum(body: bytes, received: int, rule: ChecksumRule, maybe_content: bool) -> None:
    """Refuse a wrong checksum, saying what both rules give and what the user may have meant."""
    expected = checksum(body, rule)
    if received == expected:
        return
    other = checksum(body, rule.other)
    message = (
        f"checksum {received:02X} is wrong: the {_rule_text(rule)} gives {expected:02X}, "
        f"the {_rule_text(rule.other)} {other:02X}"
    )
    if received == other:
        message += f"; it matches the {_rule_text(rule.other)}, try --checksum-from {rule.other.value}"
    elif maybe_content:
        length = body[LENGTH_AT]
        message += f"; if {received:02X} is content, the length field 0x{length:02X} does not count it"
    raise FrameRefused(message, hint=FORCE_HINT)


def _rule_text(rule: ChecksumRule) -> str:
    return "header rule" if rule is ChecksumRule.HEADER else "address rule"
