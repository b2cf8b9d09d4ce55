"""Holding an output while it is written: one writer per file, and a FIFO that never traps a signal.

Two commands told to write one file both pass ``outputs.check_outputs``
(nothing is there yet, or ``--force`` was given), so that check alone
cannot keep them apart: each would open the file and write, and neither
result would be whole (an MCAP whose chunks interleave, torn CSV rows). A
command therefore *claims* each output before it writes to it (``claimed``),
and the claim keeps the file to one writer:

- a new file is created with ``O_EXCL``: of two creators one gets it, and
  the other is refused as for any file that exists (``already exists``,
  exit 2), before it writes a byte;
- every writer holds an exclusive ``flock`` on the file for as long as it
  writes, and writes only once it holds it. ``--force`` opens an existing
  file without emptying it, takes the lock, and only then empties it, so a
  second writer, forced or not, is refused in one line (``is being written
  by another process``, exit 2) and changes nothing. The lock is the open
  file's: it ends with the writer's process, a ``kill -9`` included, and
  leaves nothing behind. A file replaced while a writer waited for it is
  claimed again under its name, so nobody writes to a file that has gone;
- a FIFO or a character device holds nothing to lose and takes no lock. A
  FIFO with no reader blocks a plain ``open`` until one comes, and a
  blocked ``open`` is resumed after every signal (PEP 475), so neither
  Ctrl-C nor SIGTERM could end the command. It is opened non-blocking
  instead, tried again every ``READER_POLL_S`` while no reader is there (a
  sleep, which a signal ends with its exception), and said once on stderr.

A sink then writes through the claim's descriptor (``open_output``): the
file it writes is the one claimed, and a FIFO's reader cannot vanish
between the claim and the write. The lock is advisory: it keeps hcrctl's
writers apart, not other programs.

A ``--log`` is appended to by design (several sessions build one history),
so it takes no lock; its lines are whole however many processes append
(``link.trafficlog`` writes each with one ``write`` to an ``O_APPEND``
descriptor). It is opened with ``open_appended``, a FIFO waited for as
above. A command whose own signal handlers only set a flag (``record``
ends on Ctrl-C by finishing its file) holds its ``--log`` with
``appended`` before it sets them, so that wait is still one a signal ends.
In the link layer, below both the feeds and the traffic log that use it.
Standard library only.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import stat
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import BinaryIO

from ..errors import HcrError
from ..errors.status import ExitStatus
from ..errors.terminal import printable

FORCE_HINT = "--force overwrites it"
#: How often a FIFO with no reader is tried again: short enough that a reader is met at once.
READER_POLL_S = 0.05
#: How many times a file replaced under a writer that was about to lock it is claimed again.
_ATTEMPTS = 8
#: What every write-only open of a stream adds: no controlling terminal, not inherited by children.
_STREAM_FLAGS = os.O_WRONLY | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0)
#: A file's: the same, never through a symbolic link (ELOOP instead).
_FLAGS = _STREAM_FLAGS | os.O_NOFOLLOW
#: A new file's permissions before the umask, as ``open()`` gives them.
_NEW_MODE = 0o666


class OutputRefused(HcrError):
    """An output that would destroy a file the user did not give up: a usage error, nothing opened."""

    exit_code = ExitStatus.USAGE


def exists_error(label: str, path: str) -> OutputRefused:
    """The refusal of an output that exists: the file named, and how to overwrite it on purpose."""
    return OutputRefused(f"{label} {path} already exists", hint=FORCE_HINT)


def symlink_error(label: str, path: str) -> OutputRefused:
    """The refusal of an output that is a symbolic link: what it points at was never named as an output."""
    return OutputRefused(
        f"{label} {path} is a symbolic link, not a file", hint="remove the link, or write elsewhere"
    )


def refuse_symlink(label: str, path: str) -> None:
    """``symlink_error`` if ``path`` is a symbolic link to a file, or to nothing; a link to a stream is not."""
    if os.path.islink(path) and _kind(path) == "file":
        raise symlink_error(label, path)


@contextlib.contextmanager
def _no_symlink(label: str, path: str) -> Iterator[None]:
    """A file open of ``path`` that met a symbolic link (O_NOFOLLOW's ELOOP) is ``symlink_error``."""
    try:
        yield
    except OSError as exc:
        if exc.errno == errno.ELOOP and os.path.islink(path):
            raise symlink_error(label, path) from None
        raise


def in_use_error(label: str, path: str) -> OutputRefused:
    """The refusal of an output another process is writing: ``--force`` cannot take it over."""
    return OutputRefused(
        f"{label} {path} is being written by another process",
        hint="wait until it ends, or write to another file",
    )


#: (st_dev, st_ino) of each output this process holds -> the descriptor holding it.
_HELD: dict[tuple[int, int], int] = {}
_HELD_LOCK = threading.Lock()


@dataclass(frozen=True)
class _Claim:
    """An output held: its descriptor, the file it names, and whether the claim made it."""

    fd: int
    target: str
    created: bool


@contextlib.contextmanager
def claimed(label: str, path: str | None, *, force: bool = False) -> Iterator[None]:
    """Hold ``path`` as this process's output for the block (None: nothing to hold).

    Refused (``OutputRefused``) when the file exists and ``force`` is not
    given, or when another writer holds it. A path that cannot be opened at
    all (a missing directory, no permission) is left to the sink's open,
    which says why in its own words. A file the claim made that is still
    empty when the block fails (the port never opened, a missing package)
    is removed: a refused or failed command leaves no file behind.
    """
    claim = None if path is None else _claim(label, path, force)
    if claim is None:
        yield
        return
    with _holding(claim.fd) as key:
        try:
            yield
        except BaseException:
            if claim.created and os.fstat(claim.fd).st_size == 0 and _identity_of(claim.target) == key:
                with contextlib.suppress(OSError):
                    os.unlink(claim.target)
            raise


@contextlib.contextmanager
def appended(label: str, path: str | None) -> Iterator[None]:
    """Hold the appended output ``path`` (a ``--log``) for the block if it is a FIFO: opened now, waited for
    here; any other file is opened when it is first written (``open_appended``)."""
    if path is None or _kind(path) != "fifo":
        yield
        return
    with _holding(open_fifo(path, f"{label} {path}")):
        yield


@contextlib.contextmanager
def _holding(fd: int) -> Iterator[tuple[int, int]]:
    """``fd`` as this process's hold on its file for the block (the file's identity), closed after."""
    key = _identity(os.fstat(fd))
    with _HELD_LOCK:
        _HELD[key] = fd
    try:
        yield key
    finally:
        with _HELD_LOCK:
            _HELD.pop(key, None)
        os.close(fd)


def open_appended(path: str, label: str = "--log") -> int:
    """A descriptor appending to ``path`` (made if missing): this process's hold on it, or opened now.

    ``O_APPEND``: each ``write`` lands whole at the end, whoever else appends.
    A FIFO is waited for as ``claimed`` waits. A symbolic link is refused
    (``OutputRefused``); any other failure is OSError as ``open``.
    """
    held = _held(path)
    if held is not None:
        return os.dup(held)
    kind = _kind(path)
    if kind == "fifo":
        return open_fifo(path, path)
    if kind == "device":
        return os.open(path, _STREAM_FLAGS | os.O_APPEND)
    refuse_symlink(label, path)
    with _no_symlink(label, path):
        return os.open(path, _FLAGS | os.O_APPEND | os.O_CREAT, _NEW_MODE)


@contextlib.contextmanager
def locked(label: str, path: str) -> Iterator[None]:
    """The writer's lock on the existing file ``path`` for the block, its bytes untouched.

    For a command that writes elsewhere and renames over ``path`` at the end
    (``outputs.written_whole``): a live recording of ``path`` keeps its
    file (this is refused), and no writer starts on it meanwhile, only to
    see it replaced. A path that cannot be opened is not locked.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        yield
        return
    try:
        if stat.S_ISREG(os.fstat(fd).st_mode):
            _lock(fd, label, path)
        yield
    finally:
        os.close(fd)


def open_output(path: str) -> BinaryIO:
    """``path`` opened to be written from its start: through this process's claim on it, if it holds one.

    Without a claim (a library caller, ``export``'s temporary file) it is
    opened as ``open(path, "wb")`` would, but a FIFO is waited for as
    ``claimed`` waits, so a signal still ends the wait. OSError as ``open``.
    """
    held = _held(path)
    fd = os.dup(held) if held is not None else _open_unclaimed(path)
    return open(fd, "wb", buffering=1 << 16)  # the caller closes it


def _held(path: str) -> int | None:
    try:
        key = _identity(os.stat(path))
    except OSError:
        return None
    with _HELD_LOCK:
        return _HELD.get(key)


def _open_unclaimed(path: str) -> int:
    kind = _kind(path)
    if kind == "fifo":
        return open_fifo(path, path)
    if kind == "device":
        return os.open(path, _STREAM_FLAGS | os.O_TRUNC)
    with _no_symlink("OUT", path):
        return os.open(path, _FLAGS | os.O_CREAT | os.O_TRUNC, _NEW_MODE)


def _claim(label: str, path: str, force: bool) -> _Claim | None:
    """``path`` held (locked, emptied if forced), or None if it cannot be opened at all."""
    refuse_symlink(label, path)
    target = os.path.realpath(path)  # the folders resolved; a link here is one to a stream
    for _ in range(_ATTEMPTS):
        kind = _kind(target)
        if kind == "fifo":
            return _Claim(open_fifo(target, f"{label} {path}"), target, created=False)
        try:
            with _no_symlink(label, target):
                opened = (
                    (os.open(target, _STREAM_FLAGS), False)
                    if kind == "device"
                    else _open_claimed(target, force)
                )
        except FileExistsError:
            raise exists_error(label, path) from None
        except OSError:
            return None
        if opened is None:
            continue  # removed between the two opens of a forced claim: try again
        fd, created = opened
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):  # a character device: a stream, nothing in it to keep
            return _Claim(fd, target, created=False)
        try:
            _lock(fd, label, path)
            if _identity(info) == _identity_of(target):
                if force:
                    os.ftruncate(fd, 0)
                return _Claim(fd, target, created)
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)  # replaced or removed while we locked it: claim what the name holds now
    raise in_use_error(label, path)


def _open_claimed(target: str, force: bool) -> tuple[int, bool] | None:
    """``target`` opened to be written, not emptied, and whether it was made now (``O_EXCL``).

    An existing file is opened only with ``force``; None if it went away
    between the two opens. FileExistsError without ``force``.
    """
    try:
        return os.open(target, _FLAGS | os.O_CREAT | os.O_EXCL, _NEW_MODE), True
    except FileExistsError:
        if not force:
            raise
    try:
        return os.open(target, _FLAGS), False
    except FileNotFoundError:
        return None


def _lock(fd: int, label: str, path: str) -> None:
    """Take the writer's lock on ``fd``; refused if another process holds it.

    A file system without locks (some network ones) cannot keep two writers
    apart this way; the claim goes on without it rather than refuse every file there.
    """
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise in_use_error(label, path) from None
    except OSError as exc:
        if exc.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.EINVAL):
            raise


def open_fifo(path: str, named: str) -> int:
    """A FIFO's writing end, waiting for a reader so that a signal still ends the wait.

    ``named`` is how the wait is said (``OUT run.csv``). Opened non-blocking,
    which fails at once (ENXIO) while no reader is there, then made blocking
    again once open, so writes wait for the reader as usual.
    """
    said = False
    while True:
        try:
            fd = os.open(path, _STREAM_FLAGS | os.O_NONBLOCK)
        except OSError as exc:
            if exc.errno != errno.ENXIO:
                raise
            if not said:
                print(
                    f"hcrctl: waiting for a reader of {printable(named)} (a FIFO)",
                    file=sys.stderr,
                    flush=True,
                )
                said = True
            time.sleep(READER_POLL_S)
            continue
        os.set_blocking(fd, True)
        return fd


def _kind(path: str) -> str:
    """``fifo``, ``device`` (a character device: ``/dev/null``), or ``file`` (anything else, or nothing yet)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return "file"
    return "fifo" if stat.S_ISFIFO(mode) else "device" if stat.S_ISCHR(mode) else "file"


def _identity(info: os.stat_result) -> tuple[int, int]:
    return info.st_dev, info.st_ino


def _identity_of(path: str) -> tuple[int, int] | None:
    try:
        return _identity(os.stat(path))
    except OSError:
        return None
