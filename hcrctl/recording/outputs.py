"""What a command may do to the files it writes: the one policy behind ``--force``.

Nothing a user records may be lost or overwritten silently, so every command
that writes a file (``record``, ``export``, the bridge's ``--mcap``) asks
``check_outputs`` before it opens anything, and a refusal is a usage error
(exit 2, one line naming the file): an existing file is kept unless
``--force`` is given; an output that is one of the command's inputs (a
symlink or a hard link to it counts: file identity is compared, not names)
or that two outputs of one command share is refused, with or without
``--force``, since then one would destroy the other mid-way.

An output that is a character device or a FIFO (``/dev/null``, a named
pipe another program reads) holds nothing to lose: it is written as it is.
A directory is never an output, nor a symbolic link to a file
(``claims.refuse_symlink``: writing through it would overwrite a file the user
never named); a command that writes only files (``config init``) refuses a
stream too (``regular_only``), since a FIFO would hold it waiting for a reader.

``written_whole`` is for a command that makes a file in one go (``export``):
it writes beside the target and renames over it only once everything is
written, so a failure (a bad input line, a full disk, Ctrl-C) leaves the
target as it was and no half file. A live recording must not work that way:
it has to be readable under its own name while it runs, and after a kill -9.

These checks are made before anything is opened, so a refusal costs
nothing; they cannot keep two processes apart, which may both pass them.
What does is the claim a writer then takes on its file (``claims``): a new
file created exclusively, and a lock held while it is written, so a second
``record`` of one file (``--force`` or not) is refused before it writes.
``written_whole`` holds that lock on the file it is about to replace.

No Click here (standard library and the errors only), so the bridge's feed code can use it as the CLI does.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterator, Sequence

from ..errors import HcrError
from ..link import claims
from ..link.claims import FORCE_HINT, OutputRefused, exists_error
from .sinks import SinkWriteError

#: (label, path): the label is what the user typed to name it (``OUT``, ``--log``, ``--mcap``);
#: a path of None (an option not given) is skipped.
Named = tuple[str, str | None]

__all__ = ["FORCE_HINT", "Named", "OutputRefused", "check_outputs", "exists_error", "written_whole"]


def check_outputs(
    outputs: Sequence[Named],
    inputs: Sequence[Named] = (),
    *,
    appended: Sequence[Named] = (),
    force: bool = False,
    regular_only: bool = False,
) -> None:
    """Refuse (``OutputRefused``) what writing ``outputs`` would destroy; call it before opening anything.

    ``outputs`` are written from scratch: an existing file among them needs
    ``force``. ``appended`` are outputs added to by design (``--log``): they
    may exist, but no other output may share their file. ``inputs`` are read
    while the outputs are written: no output may be one of them. Appended
    outputs are not compared with the inputs: a command that never writes
    its ``--log`` (``export``) may well read that very log.
    """
    written, added = _given(outputs), _given(appended)
    for label, path in written + added:
        claims.refuse_symlink(label, path)
    _refuse_directories(written + added)
    if regular_only:
        _refuse_streams(written)
    _refuse_inputs(written, _given(inputs))
    _refuse_shared(written + added)
    if not force:
        for label, path in written:
            if holds_data(path):
                raise exists_error(label, path)


def _refuse_directories(outputs: list[tuple[str, str]]) -> None:
    for label, path in outputs:
        if os.path.isdir(path):
            raise OutputRefused(f"{label} {path} is a directory", hint="give a file name")


#: What a path that is not a regular file is, as a refusal names it.
_KINDS = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"), (stat.S_ISSOCK, "a socket"))


def _refuse_streams(outputs: list[tuple[str, str]]) -> None:
    for label, path in outputs:
        mode = _mode_of(path)
        if mode is not None and not stat.S_ISREG(mode):
            kind = next((name for test, name in _KINDS if test(mode)), "a special file")
            raise OutputRefused(
                f"{label} {path} is {kind}, not a regular file", hint="remove it, or write elsewhere"
            )


def _refuse_inputs(outputs: list[tuple[str, str]], inputs: list[tuple[str, str]]) -> None:
    """An output that is an input would be emptied before it is read (or while it is)."""
    for label, path in outputs:
        for in_label, in_path in inputs:
            if same_file(path, in_path):
                raise OutputRefused(
                    f"{label} {path} is the same file as the input {in_label} {in_path}",
                    hint=f"write {label} to another file",
                )


def _refuse_shared(outputs: list[tuple[str, str]]) -> None:
    """Two writers on one file interleave or truncate each other: neither result would be whole."""
    for at, (label, path) in enumerate(outputs):
        for other_label, other_path in outputs[at + 1 :]:
            if same_file(path, other_path):
                raise OutputRefused(
                    f"{label} {path} and {other_label} {other_path} are the same file",
                    hint="give each output a file of its own",
                )


def _given(named: Sequence[Named]) -> list[tuple[str, str]]:
    return [(label, path) for label, path in named if path is not None]


def same_file(a: str, b: str) -> bool:
    """``a`` and ``b`` are one file: the same inode if both exist, else the same path once resolved.

    Names are not enough: a symlink or a hard link to a file is that file,
    and ``./x`` is ``x``. For a path that does not exist yet, its resolved
    path is the file it will be (a dangling symlink included).
    """
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet), or cannot be looked at
        return os.path.realpath(a) == os.path.realpath(b)


def holds_data(path: str) -> bool:
    """Writing ``path`` from scratch would destroy something: it exists and is not a stream.

    A character device or a FIFO is a stream (``/dev/null``, a pipe to a
    reader): writing it loses nothing. A path that cannot be looked at is
    left to the open to report (it fails there, with the reason).
    """
    mode = _mode_of(path)
    return mode is not None and not _is_stream(mode)


def _mode_of(path: str) -> int | None:
    """``path``'s mode (symlinks followed), or None if there is nothing there to look at."""
    try:
        return os.stat(path).st_mode
    except OSError:
        return None


def _is_stream(mode: int) -> bool:
    return stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)


@contextlib.contextmanager
def written_whole(path: str, label: str = "OUT", *, force: bool = False) -> Iterator[str]:
    """A temporary path beside ``path`` to write to, renamed over ``path`` when the block ends well.

    The temporary file keeps ``path``'s suffix (it may choose the format)
    and is hidden (``.NAME.XXXX.part.SUFFIX``); it is removed if the block
    raises, whatever it raises, and an error that names it names ``path``. A symbolic link to a file is
    refused (``claims.refuse_symlink``); a stream (``/dev/null``, a FIFO) is written directly. Without ``force``, a file that appeared at ``path``
    meanwhile is not replaced (``OutputRefused``, as ``check_outputs``
    would have said); with ``force`` the file to be replaced is locked as
    a writer's (``claims.locked``) until it is, so a live recording of it
    is not swept away (this is refused instead). A temporary file that cannot be made is ``SinkWriteError`` naming ``path``.
    The result has the mode the replaced file had, or the one a new file gets.
    """
    claims.refuse_symlink(label, path)
    target = os.path.realpath(path)
    mode = _mode_of(target)
    if mode is not None and _is_stream(mode):
        yield path
        return
    with claims.locked(label, path) if force and mode is not None else contextlib.nullcontext():
        yield from _written_beside(target, mode, label, path, force)


def _written_beside(target: str, mode: int | None, label: str, path: str, force: bool) -> Iterator[str]:
    """``written_whole``'s temporary file beside ``target``: yielded, then published or removed."""
    folder, name = os.path.split(target)
    try:
        handle, temp = tempfile.mkstemp(
            prefix=f".{name[:64]}.", suffix=f".part{os.path.splitext(name)[1]}", dir=folder
        )
    except OSError as exc:  # a missing or read-only directory: said as a write to the target would say it
        raise SinkWriteError(path, exc.strerror or str(exc)) from None
    try:
        os.close(handle)
        os.chmod(temp, stat.S_IMODE(mode) if mode is not None else _new_file_mode())
        yield temp
        _publish(temp, target, label, path, force)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(temp)
        if isinstance(exc, HcrError):  # the temporary name is ours: a failure to write it is the target's
            exc.message = exc.message.replace(temp, path)
            if vars(exc).get("path") == temp:
                vars(exc)["path"] = path
        raise


def _new_file_mode() -> int:
    """The permissions ``open()`` gives a new file: 0666 less the umask (mkstemp's are 0600)."""
    umask = os.umask(0o022)  # the only way to read it; set back at once (a command runs on one thread)
    os.umask(umask)
    return 0o666 & ~umask


def _publish(temp: str, target: str, label: str, path: str, force: bool) -> None:
    """Put the finished ``temp`` at ``target``: over it with ``force``, else only if it is still free.

    Without ``force`` a hard link is made (it fails if the name is taken,
    with no window in between), then the temporary name dropped; a
    filesystem without hard links gets a last look and a rename.
    """
    if force:
        os.replace(temp, target)
        return
    try:
        os.link(temp, target)
    except FileExistsError:
        raise exists_error(label, path) from None
    except OSError:  # no hard links here (vfat, some network filesystems)
        if os.path.lexists(target):
            raise exists_error(label, path) from None
        os.replace(temp, target)
        return
    os.unlink(temp)
