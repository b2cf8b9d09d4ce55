"""The stop line: anyone may stop a robot whose serial port another hcrctl holds.

A local serial device is opened exclusively, so a second program on it is
told "the port is busy". Stop must still get through: every hcrctl that holds
a local device (a path, not a URL) listens on a Unix socket named for that
device, and ``hcrctl stop`` on a busy port asks the holder there. The holder
stops at once, through whoever owns its motion, and answers only once the
stop was written and the robot answered, or says that it did not.

The rules of the socket:

- its name is a hash of the device's real path, so a /dev/serial/by-id link
  and the device node it points to meet at the same socket;
- it lives in ``$XDG_RUNTIME_DIR/hcrctl`` when that is set, else in a
  directory of this user's under /tmp (mode 0700: only the same user may
  stop through it; anyone else stops with the power switch or by the port);
- a socket left by a killed holder refuses connections: the next holder
  replaces it, and an asker reads the refusal as "no holder";
- one thread hears every asker at once, each bounded in size and time, so a
  slow or dead asker delays no stop; the stops asked by then are one stop,
  and each asker is told its outcome.

Standard library only (and the one reader of a peer's JSON): the link layer's owners decide what stopping means
(``answer``); this module only carries the question and the outcome.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import selectors
import socket
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ..inputs import peer_json

#: The one request there is.
REQUEST = b"stop\n"
#: The most bytes read of a request or an answer: anything longer is no stop line's.
MAX_MESSAGE = 4096
#: How long either side waits for the other to send its part (not the holder's stop itself).
IO_TIMEOUT_S = 2.0
#: How long an asker waits for the outcome: the holder's stop plus its robot's answer, with retries.
ANSWER_WAIT_S = 15.0
#: The most askers heard at once; past it the oldest is dropped (each had its IO_TIMEOUT_S).
MAX_ASKERS = 16
#: How often the accept thread looks up to see whether the port is closing.
ACCEPT_SLICE_S = 0.2

DELIVERED, WRITTEN, NOT_DELIVERED = "delivered", "written", "not delivered"


@dataclass(frozen=True)
class Outcome:
    """What came of a stop asked through the line: ``state`` one of the three above."""

    state: str
    took_s: float = 0.0
    holder: str = ""
    why: str = ""

    @property
    def delivered(self) -> bool:
        return self.state == DELIVERED

    def line(self, port: str) -> str:
        """The outcome in one line, as every asker says it."""
        held = f" (held by {self.holder})" if self.holder else ""
        if self.state == DELIVERED:
            return f"stop delivered on {port}{held} after {self.took_s:.3f} s: the robot answered"
        if self.state == WRITTEN:
            return f"stop written to {port}{held}, but nothing answered: the robot may still be moving"
        why = f": {self.why}" if self.why else ""
        return f"stop NOT delivered on {port}{held}{why}"


#: The holder's side: stop now for the asker named by the argument; the outcome.
Answer = Callable[[str], Outcome]


def device_of(port: str) -> str | None:
    """The real path of ``port`` when it is a local device (a path); None for a URL (socket://, sim://...)."""
    if not port or "://" in port:
        return None
    return os.path.realpath(port)


def _dirs() -> list[Path]:
    """Where stop lines live, the holder's first: the runtime directory, then this user's under /tmp."""
    found = []
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime:
        found.append(Path(runtime) / "hcrctl")
    found.append(Path("/tmp") / f"hcrctl-{os.getuid()}")  # fixed, not $TMPDIR: asker and holder must agree
    return found


def _name(device: str) -> str:
    return f"stop-{hashlib.sha256(device.encode()).hexdigest()[:16]}.sock"


def _private_dir(path: Path) -> bool:
    """Make ``path`` (mode 0700); whether it is this user's own and private (never listen in another's)."""
    with contextlib.suppress(FileExistsError):
        path.mkdir(mode=0o700, parents=True)
    info = path.lstat()
    return (
        path.is_dir() and not path.is_symlink() and info.st_uid == os.getuid() and info.st_mode & 0o077 == 0
    )


def _asker(conn: socket.socket) -> str:
    """Who asks, by the kernel's word (the peer's pid), never by what it says."""
    with contextlib.suppress(OSError, AttributeError, struct.error):
        pid, _, _ = struct.unpack("3i", conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, 12))
        return f"another program (pid {pid})"
    return "another program"


class StopLine:
    """The holder's end: listens while the port is open, answers each stop with ``answer``'s outcome."""

    def __init__(self, path: Path, sock: socket.socket, answer: Answer) -> None:
        self.path = path
        self._sock = sock
        self._answer = answer
        self._inode = path.stat().st_ino
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="hcrctl-stopline", daemon=True)
        self._thread.start()

    @classmethod
    def listen(cls, port: str, answer: Answer) -> StopLine | None:
        """Listen for stops on ``port``'s line; None for a URL, or where no private directory can be had."""
        device = device_of(port)
        if device is None:
            return None
        for home in _dirs():  # the next place when one will not do (not private, a path too long)
            try:
                if _private_dir(home):
                    path = home / _name(device)
                    return cls(path, _bind(path), answer)
            except OSError:
                continue
        return None  # no stop line is no reason to refuse the port: it only cannot be asked

    def close(self) -> None:
        """Stop listening (a stop being answered is finished first) and remove the socket if still ours."""
        self._closing.set()
        _answers(self.path)  # a knock wakes the accept at once, not a slice later
        self._thread.join(timeout=ANSWER_WAIT_S)
        with contextlib.suppress(OSError):
            self._sock.close()
        with contextlib.suppress(OSError):
            if self.path.stat().st_ino == self._inode:
                self.path.unlink()

    def _serve(self) -> None:
        """Accept and read every asker at once (none waits behind a slow one); answer the stops asked."""
        with selectors.DefaultSelector() as sel:
            sel.register(self._sock, selectors.EVENT_READ)
            askers: dict[socket.socket, _Asker] = {}
            try:
                while not self._closing.is_set():
                    for key, _ in sel.select(ACCEPT_SLICE_S):
                        if key.fileobj is self._sock:
                            self._accept(sel, askers)
                        else:
                            askers[key.fileobj].hear()  # type: ignore[index]
                    self._answer_asked(askers)
                    for conn in [c for c, a in askers.items() if a.done or a.late()]:
                        sel.unregister(conn)
                        askers.pop(conn).conn.close()
            finally:
                for asker in askers.values():
                    asker.conn.close()

    def _accept(self, sel: selectors.BaseSelector, askers: dict[socket.socket, _Asker]) -> None:
        try:
            conn, _ = self._sock.accept()
        except OSError:
            return
        if len(askers) >= MAX_ASKERS:  # the oldest makes room: it had its IO_TIMEOUT_S share
            oldest = next(iter(askers))
            sel.unregister(oldest)
            askers.pop(oldest).conn.close()
        conn.setblocking(False)
        askers[conn] = _Asker(conn)
        sel.register(conn, selectors.EVENT_READ)

    def _answer_asked(self, askers: dict[socket.socket, _Asker]) -> None:
        """One stop for everyone who asked by now; each told its outcome."""
        asked = [a for a in askers.values() if a.asked and not a.done]
        if not asked or self._closing.is_set():
            return
        try:
            outcome = self._answer(asked[0].who)
        except Exception as exc:  # the holder could not even try: said, never a dead line
            outcome = Outcome(NOT_DELIVERED, why=f"the holder failed ({exc})")
        told = json.dumps(asdict(outcome)).encode() + b"\n"
        for asker in asked:
            asker.tell(told)


class _Asker:
    """One connection: what it sent so far, by when it must have asked, who it is."""

    def __init__(self, conn: socket.socket) -> None:
        self.conn = conn
        self.who = _asker(conn)
        self.data = b""
        self.deadline = time.monotonic() + IO_TIMEOUT_S
        self.done = False

    @property
    def asked(self) -> bool:
        return self.data.split(b"\n", 1)[0].strip() == REQUEST.strip() and b"\n" in self.data

    def late(self) -> bool:
        return not self.asked and time.monotonic() > self.deadline

    def hear(self) -> None:
        try:
            chunk = self.conn.recv(MAX_MESSAGE)
        except BlockingIOError:
            return
        except OSError:
            chunk = b""
        self.data += chunk
        if not chunk or len(self.data) > MAX_MESSAGE or (b"\n" in self.data and not self.asked):
            self.done = True  # gone, too long, or not a stop: dropped unanswered

    def tell(self, told: bytes) -> None:
        self.done = True
        with contextlib.suppress(OSError):
            self.conn.settimeout(IO_TIMEOUT_S)
            self.conn.sendall(told)


def _bind(path: Path) -> socket.socket:
    """A listening socket at ``path``; one a dead holder left (it refuses) is replaced, a live one is not."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        try:
            sock.bind(str(path))
        except OSError as exc:
            if exc.errno != errno.EADDRINUSE or _answers(path):
                raise
            path.unlink()
            sock.bind(str(path))
        sock.listen(MAX_ASKERS)
    except BaseException:
        sock.close()
        raise
    return sock


def _answers(path: Path) -> bool:
    """Whether a holder listens at ``path`` (a dead one's socket refuses)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
        probe.settimeout(IO_TIMEOUT_S)
        try:
            probe.connect(str(path))
        except OSError:
            return False
    return True


def _read_line(conn: socket.socket) -> bytes:
    data = b""
    while b"\n" not in data and len(data) < MAX_MESSAGE:
        chunk = conn.recv(MAX_MESSAGE - len(data))
        if not chunk:
            break
        data += chunk
    return data.split(b"\n", 1)[0].strip()


def ask(port: str, wait: float = ANSWER_WAIT_S) -> Outcome | None:
    """Ask the program holding ``port`` to stop; its outcome, or None when no holder listens.

    A holder that takes the question but never answers within ``wait`` is a
    stop NOT known to be delivered, said as such.
    """
    device = device_of(port)
    if device is None:
        return None
    for home in _dirs():
        path = home / _name(device)
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as conn:
            conn.settimeout(IO_TIMEOUT_S)
            try:
                conn.connect(str(path))
                conn.sendall(REQUEST)
            except OSError:
                continue  # none here, or a dead holder's socket: try the next place
            conn.settimeout(wait)
            try:
                reply = _read_line(conn)
            except OSError:
                return Outcome(NOT_DELIVERED, why=f"the holder did not answer within {wait:g} s")
            if not reply:  # it let go of the port as the question came (its own end sends its stop)
                return Outcome(NOT_DELIVERED, why="the holder closed the port before answering; try again")
            return _outcome(reply)
    return None


def _outcome(reply: bytes) -> Outcome:
    """The holder's answer, read as any peer's JSON is; its words kept printable (they reach a terminal)."""
    try:
        data: Any = peer_json(reply)
        state, took, holder, why = data["state"], float(data["took_s"]), data["holder"], data["why"]
    except (ValueError, KeyError, TypeError):
        return Outcome(NOT_DELIVERED, why="the holder's answer made no sense")
    if state not in (DELIVERED, WRITTEN, NOT_DELIVERED):
        return Outcome(NOT_DELIVERED, why="the holder's answer made no sense")
    return Outcome(state, took, _printable(holder), _printable(why))


def _printable(text: object) -> str:
    return "".join(ch for ch in str(text) if ch.isprintable())[:200]
