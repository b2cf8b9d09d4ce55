"""Single keys from the terminal, without Enter, arrows decoded.

``KeyReader`` puts a terminal in cbreak mode (no echo, no line buffering,
but Ctrl-C and Ctrl-Z still work, so Ctrl-C stays a KeyboardInterrupt that
unwinds and stops the robot) and always puts the old mode back: its ``__exit__``
runs on every way out, including ``Terminated`` from SIGTERM/SIGHUP.

``KeyDecoder`` is the sans-IO half: bytes in, key names out. An arrow key is
three bytes (ESC [ A), and a held key arrives as a burst of them, so input is
buffered and split; an ESC with nothing after it is the Escape key itself.

A terminal that speaks the kitty keyboard protocol can also say when a key is
released, which a terminal otherwise never does. ``KeyReader.use_kitty``
probes for it as the protocol's specification recommends (``CSI ? u``, then
the primary device attributes request, whose answer every terminal sends:
a kitty answer before it means the protocol is there), pushes the flags
"disambiguate", "report event types" and "report all keys as escape codes",
and pops them on every way out. Its key events decode to the same names, and
a release to ``release:<name>``.
"""

from __future__ import annotations

import os
import select
import sys
import time
from typing import IO, Any

from ..stdout import write_to

ESC = 0x1B
#: How long to wait for the rest of an escape sequence before calling it ESC.
ESC_WAIT = 0.03

#: Final bytes of CSI (ESC [ x) and SS3 (ESC O x) sequences that we name.
SEQUENCES = {"A": "up", "B": "down", "C": "right", "D": "left", "H": "home", "F": "end"}
#: The kitty flags pushed: 1 disambiguate, 2 report event types, 8 report all keys as escape codes.
KITTY_FLAGS = 1 | 2 | 8
#: How long the probe waits for the answer to the device attributes request, which every terminal
#: sends within milliseconds: only one that never answers (a bare pty) waits this long.
PROBE_WAIT = 1.0
#: The kitty protocol's event types: 1 press, 2 repeat, 3 release.
RELEASE = 3
#: Kitty key codes with names of their own (the rest are their Unicode character).
KITTY_CODES = {27: "esc", 13: "enter", 9: "tab", 127: "backspace", 8: "backspace"}
CTRL = 4
CONTROLS = {
    0x03: "ctrl-c",
    0x04: "ctrl-d",
    0x09: "tab",
    0x0A: "enter",
    0x0D: "enter",
    0x7F: "backspace",
    0x08: "backspace",
}


class KeyDecoder:
    """Bytes to key names: "q", " ", "up", "ctrl-d", "esc"..."""

    def __init__(self) -> None:
        self._buffer = bytearray()

    @property
    def pending(self) -> bool:
        return bool(self._buffer)

    def feed(self, data: bytes) -> list[str]:
        self._buffer += data
        keys: list[str] = []
        while self._buffer:
            key, used = _next_key(bytes(self._buffer))
            if used == 0:
                break  # an escape sequence still arriving
            del self._buffer[:used]
            if key:
                keys.append(key)
        return keys

    def flush(self) -> list[str]:
        """What is left once no more bytes are coming: a lone ESC is the Escape key."""
        keys = []
        while self._buffer:
            key, used = _next_key(bytes(self._buffer), final=True)
            del self._buffer[: max(used, 1)]
            if key:
                keys.append(key)
        return keys


def _next_key(data: bytes, final: bool = False) -> tuple[str, int]:
    """The first key in ``data`` and how many bytes it took (0: need more)."""
    first = data[0]
    if first != ESC:
        return _plain(data, final)
    if len(data) == 1:
        return ("esc", 1) if final else ("", 0)
    if data[1] not in b"[O":
        return "esc", 1  # ESC then an ordinary key (Alt+key): the ESC on its own
    for end in range(2, len(data)):
        if 0x40 <= data[end] <= 0x7E:
            if data[1] == ord("[") and end > 2:
                return _csi(data[2:end].decode("ascii", "replace"), chr(data[end])), end + 1
            return SEQUENCES.get(chr(data[end]), ""), end + 1
    return ("esc", 1) if final else ("", 0)


def _csi(params: str, final: str) -> str:
    """A CSI sequence with parameters: a kitty key event, an answer to a probe, or an arrow with modifiers."""
    if params.startswith("?"):
        if final == "u":
            return f"kitty-flags:{params[1:]}"
        return "device-attributes" if final == "c" else ""
    fields = [part.split(":") for part in params.split(";")]
    modifiers, event = _number(fields, 1, 0, 1), _number(fields, 1, 1, 1)
    code = _number(fields, 0, 0, 0)
    name = _kitty_key(code, modifiers - 1) if final == "u" else SEQUENCES.get(final, "")
    if not name:
        return ""
    return f"release:{name}" if event == RELEASE else name


def _number(fields: list[list[str]], field: int, part: int, default: int) -> int:
    try:
        text = fields[field][part]
    except IndexError:
        return default
    return int(text) if text.isdigit() and len(text) <= 7 else default


def _kitty_key(code: int, mods: int) -> str:
    """A kitty key code as the name the legacy encoding would give (ctrl-c stays ctrl-c)."""
    if mods & CTRL and code in (ord("c"), ord("d")):
        return f"ctrl-{chr(code)}"
    if code in KITTY_CODES:
        return KITTY_CODES[code]
    if 0x20 <= code < 0x110000 and not 0xD800 <= code < 0xE000 and not 57344 <= code <= 63743:
        return chr(code)  # the private-use range holds kitty's functional keys: not text
    return ""


def _plain(data: bytes, final: bool) -> tuple[str, int]:
    """One character, decoded as UTF-8 when it is a multi-byte one."""
    first = data[0]
    if first in CONTROLS:
        return CONTROLS[first], 1
    size = 1 if first < 0x80 else 2 if first < 0xE0 else 3 if first < 0xF0 else 4
    if len(data) < size and not final:
        return "", 0
    return data[:size].decode("utf-8", "replace"), min(size, len(data))


class KeyReader:
    """Keys from ``stream`` (stdin), in cbreak mode when it is a terminal."""

    def __init__(self, stream: IO[Any] | None = None) -> None:
        self.stream = stream if stream is not None else sys.stdin
        self.decoder = KeyDecoder()
        self.eof = False
        self._keys: list[str] = []
        self._saved: list[Any] | None = None
        self._told_eof = False
        #: Where the kitty flags were pushed (popped on restore); None when they were not.
        self._kitty: int | None = None
        try:
            self.fd: int | None = self.stream.fileno()
        except (AttributeError, OSError, ValueError):  # no real input at all: it has ended
            self.fd = None
            self.eof = True

    @property
    def is_terminal(self) -> bool:
        return self.fd is not None and os.isatty(self.fd)

    def __enter__(self) -> KeyReader:
        if self.fd is not None and os.isatty(self.fd):
            self._saved = _cbreak(self.fd)
        return self

    def __exit__(self, *exc: object) -> None:
        self.restore()

    def use_kitty(self, out: int, wait: float = PROBE_WAIT) -> bool:
        """Probe the terminal on ``out``; switch the kitty protocol on if it answers. Keys typed meanwhile are kept."""
        if not self.is_terminal or not os.isatty(out):
            return False
        write_to(out, b"\x1b[?u\x1b[c")
        found, kept, deadline = False, [], time.monotonic() + wait
        while (left := deadline - time.monotonic()) > 0:
            key = self.read(left)
            if key is None or key == "device-attributes":
                break
            if key.startswith("kitty-flags:"):
                found = True
            elif key != "eof":
                kept.append(key)
        self._keys[:0] = kept
        if found:
            write_to(out, b"\x1b[>%du" % KITTY_FLAGS)
            self._kitty = out
        return found

    def restore(self) -> None:
        """Put the terminal back as it was; safe to call twice."""
        if self._kitty is not None:
            import contextlib

            with contextlib.suppress(OSError):
                write_to(self._kitty, b"\x1b[<u")
            self._kitty = None
        if self._saved is not None and self.fd is not None:
            import termios

            # now, not after the output drains: a terminal that stopped reading would hold the
            # change, and with it the stop and the exit, for as long as it stays stalled
            termios.tcsetattr(self.fd, termios.TCSANOW, self._saved)
            self._saved = None

    def read(self, timeout: float) -> str | None:
        """The next key, or None after ``timeout`` s; "eof" once when the input ends."""
        if self._keys:
            return self._keys.pop(0)
        fd = self.fd
        if self.eof or fd is None:  # no descriptor means the input ended at birth (eof is set)
            if not self._told_eof:
                self._told_eof = True
                return "eof"
            time.sleep(timeout)
            return None
        if not _readable(fd, timeout):
            return None
        data = os.read(fd, 1024)
        if not data:
            self.eof = self._told_eof = True
            return "eof"
        self._keys = self.decoder.feed(data)
        if self.decoder.pending and not _readable(fd, ESC_WAIT):
            self._keys += self.decoder.flush()
        return self._keys.pop(0) if self._keys else None


def _readable(fd: int, timeout: float) -> bool:
    ready, _, _ = select.select([fd], [], [], max(timeout, 0))
    return bool(ready)


def _cbreak(fd: int) -> list[Any]:
    """Echo and line editing off, signals on; returns the mode to restore."""
    import termios

    saved = termios.tcgetattr(fd)
    mode = termios.tcgetattr(fd)
    mode[3] &= ~(termios.ECHO | termios.ICANON)
    mode[6][termios.VMIN] = 1
    mode[6][termios.VTIME] = 0
    termios.tcsetattr(fd, termios.TCSAFLUSH, mode)
    return saved
