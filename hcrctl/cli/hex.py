"""``hcrctl hex decode|encode|send``: the frame debugger a firmware author reaches for.

``decode`` runs pasted hex or a binary capture through the same decoder the
client uses and gives every frame and every problem a row. ``encode`` prints
the exact bytes a one-shot command would send, with the same grammar and
ranges (generated from the command table by ``params``). ``send`` puts typed
bytes on the wire, completing or checking the checksum first.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, BinaryIO

import click

from ..errors import HexSyntaxError, InputFileError
from ..errors.status import ExitStatus
from ..hex.parse import STYLES, format_hex, parse_hex, parse_hex_args
from ..ops.motion import DRIVE_COMMANDS
from ..protocol import commands as C
from ..protocol.profiles import profile
from .params import NamedArgument, hold_option, request_value, table_command
from .settings import Settings, json_option, stdout_is_terminal

if TYPE_CHECKING:
    from ..hex.rowsinks import RowSink
    from ..link.client import Robot

STDIN_HINT = "for a binary capture use --file"


@click.group("hex")
def hex_group() -> None:
    """Decode, encode and send raw frames.

    \b
    hcrctl hex decode 55 AA 01 02 14 0D 0A 2D 0D 0A
    hcrctl hex encode drive power 60 60
    hcrctl --port sim:// hex send 55 AA 01 01 14 FF
    """


# -- decode -------------------------------------------------------------------------


@hex_group.command()
@click.argument("hex_text", nargs=-1, metavar="[HEX...|-]")
@click.option(
    "--file",
    "capture",
    type=click.Path(exists=True, dir_okay=False),
    help="Decode a binary capture file (raw bytes, not hex text).",
)
@click.option("--summary", is_flag=True, help="Counts only: frames per command and address, checksums, junk.")
@json_option
@click.pass_context
def decode(ctx: click.Context, hex_text: tuple[str, ...], capture: str | None, summary: bool) -> None:
    """Decode HEX (any common form), stdin ('-') or a capture; one row per frame or problem.

    Exit 0 if every frame is good, 1 if any frame or byte is bad, 2 if the
    input is not hex. The checksum is judged under --checksum-from; a bad one
    also shows what the other rule gives. Lines the firmware printed between
    frames (a boot banner, debug output) are rows of kind text, not junk.
    """
    settings: Settings = ctx.obj
    chunks = _decode_input(hex_text, capture)
    if summary:
        _summarise(ctx, settings, chunks)
    from ..hex.decoding import decode_to
    from ..hex.view import FrameTally

    tally, sink = FrameTally(), _row_sink(settings)
    size = decode_to(chunks, settings.checksum, tally, sink, profile(settings.protocol))
    sink.close()
    hint = tally.hint()
    click.echo(f"hcrctl: {size} bytes: {tally.text()}{f' (hint: {hint})' if hint else ''}", err=True)
    ctx.exit(ExitStatus.OK if tally.all_good else ExitStatus.FAILED)


def _encoded(settings: Settings, request: C.Request | C.Command) -> bytes:
    """The frame for ``request`` in the chosen protocol (v0.11 ends it in a lone 0A)."""
    return profile(settings.protocol).retarget(C.encode_request(request, settings.address, settings.checksum))


def _summarise(ctx: click.Context, settings: Settings, chunks: Iterator[bytes]) -> None:
    """``--summary``: the counts, as text or one JSON object; exit as decode would."""
    from ..hex.summary import Summary
    from ..protocol.dialect import make_decoder

    counts = Summary(settings.checksum)
    decoder = make_decoder(profile(settings.protocol), settings.checksum)
    for chunk in chunks:
        counts.bytes += len(chunk)
        counts.add(decoder.count(chunk, counts.heads))
    counts.add(decoder.flush())
    click.echo(_json(counts.as_dict()) if settings.as_json else counts.text())
    ctx.exit(ExitStatus.OK if counts.all_good else ExitStatus.FAILED)


def _decode_input(hex_text: tuple[str, ...], capture: str | None) -> Iterator[bytes]:
    """The input as byte chunks; a small input is read (and any typo in it found) before returning."""
    if capture is not None and hex_text:
        raise click.UsageError("give HEX arguments or --file CAPTURE, not both")
    if capture is not None:
        return _capture(capture)
    if hex_text == ("-",) or (not hex_text and not sys.stdin.isatty()):
        return _stdin_hex()
    if not hex_text:
        raise click.UsageError("give HEX bytes, '-' to read them from stdin, or --file CAPTURE")
    return iter((parse_hex_args(hex_text),))


def _capture(path: str) -> Iterator[bytes]:
    """A binary capture; an ASCII-only file cannot hold a frame (0xAA), so it is read as hex text.

    A file larger than ``WHOLE`` is judged by its first ``WHOLE`` bytes and streamed.
    """
    from ..hex.stream import WHOLE, binary_chunks, hex_line_chunks

    try:
        handle = open(path, "rb")  # noqa: SIM115 - the generators returned close it
        data = handle.read(WHOLE)
    except OSError as exc:
        raise InputFileError(path, None, f"cannot read it ({exc.strerror or exc})") from exc
    whole = len(data) < WHOLE
    if not data.isascii() or not data.strip():
        return _closing(handle, binary_chunks(data, handle), path)
    if data.lstrip().startswith(b"{"):
        handle.close()
        raise click.UsageError(
            f"{path} looks like a --log file; render it with: hcrctl monitor --from {path}"
        )
    text = data.decode("ascii")
    if not _mostly_hex(text):  # a capture of a device that only printed lines (a boot banner)
        click.echo(f"hcrctl: {path} holds printed text, not hex: decoding its bytes", err=True)
        return _closing(handle, binary_chunks(data, handle), path)
    click.echo(f"hcrctl: {path} is text, not a binary capture: reading it as hex", err=True)
    if whole:
        handle.close()
        try:
            return iter((parse_hex(text, path),))
        except HexSyntaxError as exc:  # a file's content, not usage: FILE:LINE and exit 1
            raise InputFileError(
                path, exc.line, f"not hex: {exc.token!r} at column {exc.column}", exc.hint
            ) from None
    return _closing(handle, hex_line_chunks(data, handle, path, file=True), path)


def _closing(handle: BinaryIO, chunks: Iterator[bytes], path: str) -> Iterator[bytes]:
    """The chunks, the file closed after them; a read that fails (EIO) is the file's error, not ours."""
    with handle:
        try:
            yield from chunks
        except OSError as exc:
            raise InputFileError(path, None, f"cannot read it ({exc.strerror or exc})") from exc


#: One word of hex as people write it: 55, 0x55, 55AA01, \x55\xAA, with brackets and separators around.
HEX_WORD = r"[{(\[]?((0x)?[0-9A-Fa-f]{1,2}|(\\x[0-9A-Fa-f]{2})+|[0-9A-Fa-f]+)[,:;)}\]]*"


def _mostly_hex(text: str) -> bool:
    """Whether ``text`` is hex (perhaps with a typo to report), rather than lines a firmware printed."""
    import re

    words = text.split()
    return 2 * sum(bool(re.fullmatch(HEX_WORD, w)) for w in words) >= len(words)


def _stdin_hex() -> Iterator[bytes]:
    """Hex text on stdin: whole when small (a typo stops it before any row), else line by line."""
    from ..hex.stream import WHOLE, hex_line_chunks

    stream = sys.stdin.buffer
    raw = stream.read(WHOLE)
    if len(raw) >= WHOLE:
        return hex_line_chunks(raw, stream, "stdin", STDIN_HINT)
    try:
        return iter((parse_hex(raw.decode("utf-8", errors="replace"), "stdin"),))
    except HexSyntaxError as exc:
        exc.hint = f"{exc.hint}; {STDIN_HINT}"
        raise


def _row_sink(settings: Settings) -> RowSink:
    from ..hex import rowsinks

    if settings.as_json:
        return rowsinks.JsonArraySink()
    if stdout_is_terminal():
        return rowsinks.TableSink()
    return rowsinks.PlainSink()


# -- encode -------------------------------------------------------------------------


@hex_group.group()
def encode() -> None:
    """Print the frame a command would send, without sending it.

    Same grammar and ranges as the one-shot commands, under the global
    --address and --checksum-from:

    \b
    hcrctl hex encode drive power 60 60     ->  55 AA 01 02 01 CC CC 9B 0D 0A
    hcrctl hex encode read compass          ->  55 AA 01 01 14 FF 14 0D 0A
    hcrctl --address 0x10 hex encode stop --style c
    """


def _style_option(func: Any) -> Any:
    """``--style``, and ``--json`` for the whole frame as decoded."""
    func = json_option(func)
    return click.option(
        "--style",
        type=click.Choice(STYLES),
        default="spaced",
        show_default=True,
        help="spaced: 55 AA 01; compact: 55AA01; c: {0x55, 0xAA}; escaped: \\x55\\xAA.",
    )(func)


def _encode_command(name: str, label: str | None = None) -> click.Command:
    @table_command(name, label)
    @_style_option
    @click.pass_obj
    def command(settings: Settings, style: str, **fields: Any) -> None:
        value = request_value(C.BY_NAME[name], fields)
        _print_frame(settings, _encoded(settings, value), style)

    command.help = f"{command.help}\n\nPrints the frame; sends nothing."
    return command


@encode.group("drive", help=f"drive {'|'.join(DRIVE_COMMANDS)} LEFT RIGHT, as 'hcrctl drive' takes it.")
def encode_drive() -> None:
    """(help= is built from DRIVE_COMMANDS, so it names exactly what drive takes.)"""


for _cmd in C.COMMANDS:
    if _cmd.kind == "write":
        _group = encode_drive if _cmd.name in DRIVE_COMMANDS else encode
        _group.add_command(_encode_command(_cmd.name))


@encode.command("stop")
@_style_option
@click.pass_obj
def encode_stop(settings: Settings, style: str) -> None:
    """The stop frame: motor power 0x80 0x80."""
    _print_frame(settings, _encoded(settings, C.STOP), style)


@encode.command("read")
@click.argument("sensors", nargs=-1, type=click.Choice(C.SENSORS), metavar="[SENSOR]...", cls=NamedArgument)
@_style_option
@click.pass_obj
def encode_read(settings: Settings, sensors: tuple[str, ...], style: str) -> None:
    """Read requests (content 0xFF, length 1), one line per SENSOR; none means all."""
    for name in dict.fromkeys(sensors) or C.SENSORS:
        _print_frame(settings, _encoded(settings, C.BY_NAME[name]), style)


def _print_frame(settings: Settings, frame: bytes, style: str) -> None:
    if settings.as_json:
        from ..ops.hexsend import traffic_row

        row = traffic_row(frame, settings.checksum, "tx", profile(settings.protocol))
        click.echo(_json(row))
    else:
        click.echo(format_hex(frame, style))


# -- send ---------------------------------------------------------------------------


@hex_group.command()
@click.argument("hex_text", nargs=-1, required=True, metavar="HEX...")
@click.option(
    "--force", is_flag=True, help="Send the bytes exactly as typed, even with a wrong checksum or end."
)
@hold_option("For a motion frame: stop after SECONDS (default: hold until Ctrl-C), as drive does.")
@json_option
@click.pass_context
def send(ctx: click.Context, hex_text: tuple[str, ...], force: bool, hold_for: float | None) -> None:
    """Send HEX as typed; a missing checksum and end are appended (and said).

    A checksum or end that is present but wrong is refused (exit 1) unless
    --force. A command with a reply waits up to --timeout and prints it
    decoded; the frame goes out once unless --retries is given. A motion
    frame is held like 'hcrctl drive': until --for SECONDS or Ctrl-C, then
    stop is sent.
    """
    from ..hex.typedframe import complete_frame
    from ..ops.hexsend import holds_motion, retries_set, send_frame, traffic_row

    settings: Settings = ctx.obj
    frame, note = complete_frame(
        parse_hex_args(hex_text), settings.checksum, force, profile(settings.protocol)
    )
    if note:
        click.echo(f"hcrctl: {note}", err=True)
    with settings.robot() as robot, retries_set(robot, _explicit_retries(ctx)):
        result = {"sent": traffic_row(frame, robot.rule, "tx", robot.profile), "reply": None}
        result["reply"] = send_frame(robot, frame)
        _report(settings, result)
        if holds_motion(robot, frame) and settings.shared_robot is None:
            _hold_motion(robot, hold_for)


def _report(settings: Settings, result: dict[str, Any]) -> None:
    from ..hex.view import summary_text

    if settings.as_json:
        click.echo(_json(result))
        return
    click.echo(f"sent   {result['sent']['hex']}   {summary_text(result['sent'])}")
    if result["reply"] is not None:
        click.echo(f"reply  {result['reply']['hex']}   {summary_text(result['reply'])}")


def _hold_motion(robot: Robot, hold_for: float | None) -> None:
    """Hold like ``drive``, then stop every address the frame moved (which need not be --address) and ours."""
    from ..link.rescue import stopping
    from ..ops.motion import hold
    from .output import say

    until = f"for {hold_for:g} s" if hold_for is not None else "until Ctrl-C"
    say(f"holding the motion {until} — Ctrl-C to stop")
    with stopping(robot):
        held = hold(robot, hold_for)
    say(f"stopped after {held:.3g} s")


def _explicit_retries(ctx: click.Context) -> int | None:
    """--retries when the user set it (flag, env or config); None means send once."""
    from click.core import ParameterSource

    root = ctx.find_root()
    source = root.get_parameter_source("retries")
    return ctx.obj.retries if source not in (None, ParameterSource.DEFAULT) else None


def _json(value: Any) -> str:
    """``json.dumps`` without ASCII escapes; json is imported here, where the output is JSON
    (``hex decode --summary`` and ``--file`` start without it)."""
    import json

    return json.dumps(value, ensure_ascii=False)
