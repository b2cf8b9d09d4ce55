"""Single keys from the terminal, without Enter, arrows decoded.

``KeyReader`` puts a terminal in cbreak mode (no echo, no line buffering,
but Ctrl-C and Ctrl-Z still work, so Ctrl-C stays a KeyboardInterrupt that
unwinds and stops the robot) and always puts the old mode back: its ``__exit__``
runs on every way out, including ``Terminated`` from SIGTERM/SIGHUP.

``KeyDecoder`` is the sans-IO half: bytes in, key names out. An arrow key is
three bytes (ESC [ A), and a held key arrives as a burst of them, so input is
buffered and split; an ESC with nothing after it is the Escape key itself.
"""

from __future__ import annotations

import os
import select
import sys
import time
from typing import IO, Any

ESC = 0x1B
#: How long to wait for the rest of an escape sequence before calling it ESC.
ESC_WAIT = 0.03

#: Final bytes of CSI (ESC [ x) and SS3 (ESC O x) sequences that we name.
SEQUENCES = {"A": "up", "B": "down", "C": "right", "D": "left", "H": "home", "F": "end"}
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
            return SEQUENCES.get(chr(data[end]), ""), end + 1
    return ("esc", 1) if final else ("", 0)


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

    def restore(self) -> None:
        """Put the terminal back as it was; safe to call twice."""
        if self._saved is not None and self.fd is not None:
            import termios

            termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)
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
