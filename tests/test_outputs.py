"""Nothing a user records is lost or overwritten silently: ``record``'s and ``export``'s outputs.

The installed executable is run against files the test made: every refusal
must exit 2 on one line naming the file(s), leave every file as it was (its
bytes and its mtime) and, for ``record``, leave the port unopened and the
wire silent. ``export`` writes beside its target and renames at the end, so
a log that breaks off mid-way, a signal or a file that appears meanwhile
leaves the directory exactly as it was.
"""

from __future__ import annotations

import errno
import functools
import os
import signal
import subprocess
from pathlib import Path

import pytest
from helpers_cli import clean_env, finish, one_line, run, start, stderr_until, wait_until, wire
from helpers_mcap import small_tmpfs

SUFFIXES = [".mcap", ".csv"]
OLD = b"an earlier recording, not to be lost\n"


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real traffic log: a read of every sensor on the simulator."""
    home = tmp_path_factory.mktemp("outputs")
    path = home / "session.jsonl"
    done = run(["--port", "sim://", "--log", str(path), "read"], clean_env(home))
    assert done.returncode == 0, done.stderr
    assert path.read_text().count("\n") >= 6
    return path


def state(path: Path) -> tuple[bytes, int]:
    """What a refusal must not change: the file's bytes and its modification time."""
    return path.read_bytes(), path.stat().st_mtime_ns


def existing(path: Path) -> tuple[bytes, int]:
    path.write_bytes(OLD)
    return state(path)


def listing(folder: Path) -> list[str]:
    """Every name in ``folder``, hidden ones (a temporary file) included."""
    return sorted(os.listdir(folder))


def refused(done: subprocess.CompletedProcess[str], *named: object) -> str:
    """The one-line usage error of a refusal, which names every path given."""
    assert done.returncode == 2, done.stderr
    line = one_line(done.stderr)
    assert "Traceback" not in done.stderr
    for name in named:
        assert str(name) in line, line
    return line


# -- an existing output -------------------------------------------------------------------


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_export_refuses_an_existing_out_and_leaves_it_as_it_was(
    log: Path, tmp_path: Path, suffix: str
) -> None:
    out = tmp_path / f"old{suffix}"
    before = existing(out)
    line = refused(run(["export", str(log), str(out)], clean_env(tmp_path)), out, "--force")
    assert "exists" in line
    assert state(out) == before
    assert listing(tmp_path) == [out.name]


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_export_force_overwrites(log: Path, tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"old{suffix}"
    existing(out)
    done = run(["export", str(log), str(out), "--force"], clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    written = out.read_bytes()
    assert OLD not in written
    assert written.startswith(b"\x89MCAP" if suffix == ".mcap" else b"time,t,direction,address,command,")
    assert listing(tmp_path) == [out.name]  # no temporary file left beside it


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_record_refuses_an_existing_out_before_the_port_is_touched(tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"old{suffix}"
    before = existing(out)
    with wire() as tap:
        done = run(["--port", tap.path, "record", str(out)], clean_env(tmp_path))
        assert tap.read(quiet=0.3) == b""  # the process has ended: anything it wrote is there already
    refused(done, out, "--force")
    assert state(out) == before


def test_record_refuses_before_opening_the_port(tmp_path: Path) -> None:
    """A port that cannot open would be exit 1 naming the port, had it been opened first."""
    out = tmp_path / "old.csv"
    before = existing(out)
    port = tmp_path / "no-such-port"
    line = refused(run(["--port", str(port), "record", str(out)], clean_env(tmp_path)), out, "--force")
    assert str(port) not in line
    assert state(out) == before


def test_record_force_overwrites(tmp_path: Path) -> None:
    out = tmp_path / "old.csv"
    existing(out)
    args = ["--port", "sim://", "record", str(out), "compass", "--duration", "0.3", "--force"]
    done = run(args, clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    lines = out.read_text().splitlines()
    assert lines[0].startswith("time,t,direction,address,command,")
    assert OLD.decode().strip() not in lines


# -- an output that is an input, or another output -------------------------------------


def input_as_out(kind: str, log: Path, folder: Path) -> tuple[Path, Path]:
    """(LOG, OUT) naming one file: the same name, a symlink to it, or a hard link to it."""
    source = folder / "session.mcap"  # a log with the suffix of an output: nothing else stops it
    source.write_bytes(log.read_bytes())
    if kind == "same name":
        return source, source
    out = folder / "out.mcap"
    if kind == "symlink":
        out.symlink_to(source.name)
    elif kind == "hard link":
        os.link(source, out)
    else:  # another spelling of the same path
        (folder / "sub").mkdir()
        out = folder / "sub" / ".." / source.name
    return source, out


@pytest.mark.parametrize("kind", ["same name", "symlink", "hard link", "another spelling"])
@pytest.mark.parametrize("force", [False, True])
def test_export_refuses_to_write_its_own_input(log: Path, tmp_path: Path, kind: str, force: bool) -> None:
    source, out = input_as_out(kind, log, tmp_path)
    before, names = state(source), listing(tmp_path)
    args = ["export", str(source), str(out), *(["--force"] if force else [])]
    line = refused(run(args, clean_env(tmp_path)), out)
    assert ("is a symbolic link" if kind == "symlink" else "same file") in line  # the true reason
    assert state(source) == before
    assert listing(tmp_path) == names


@pytest.mark.parametrize("force", [False, True])
def test_record_refuses_an_out_that_is_its_log(tmp_path: Path, force: bool) -> None:
    out = tmp_path / "run.csv"
    with wire() as tap:
        args = ["--port", tap.path, "--log", str(out), "record", str(out), *(["--force"] if force else [])]
        done = run(args, clean_env(tmp_path))
        assert tap.read(quiet=0.3) == b""
    line = refused(done, out, "--log")
    assert "same file" in line
    assert listing(tmp_path) == []  # neither the recording nor the log was opened


def test_record_refuses_an_existing_log_linked_to_its_out(tmp_path: Path) -> None:
    """An existing --log is fine (it is appended to); a link to it as the recording's file is not."""
    log, out = tmp_path / "wire.jsonl", tmp_path / "run.mcap"
    before = existing(log)
    out.symlink_to(log.name)
    with wire() as tap:
        args = ["--port", tap.path, "--log", str(log), "record", str(out), "--force"]
        done = run(args, clean_env(tmp_path))
        assert tap.read(quiet=0.3) == b""
    assert "is a symbolic link" in refused(done, out)
    assert state(log) == before


@pytest.mark.parametrize("force", [False, True])
def test_export_refuses_an_out_that_is_the_log_option(log: Path, tmp_path: Path, force: bool) -> None:
    out = tmp_path / "out.mcap"
    args = ["--log", str(out), "export", str(log), str(out), *(["--force"] if force else [])]
    line = refused(run(args, clean_env(tmp_path)), out, "--log")
    assert "same file" in line
    assert listing(tmp_path) == []


def test_an_existing_log_is_appended_to_while_recording(tmp_path: Path) -> None:
    log, out = tmp_path / "wire.jsonl", tmp_path / "run.csv"
    before, _ = existing(log)
    args = ["--port", "sim://", "--log", str(log), "record", str(out), "compass", "--duration", "0.3"]
    done = run(args, clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    after = log.read_bytes()
    assert after.startswith(before) and b'"direction": "tx"' in after[len(before) :]
    assert out.read_text().startswith("time,t,")


def test_export_may_read_the_log_named_by_the_log_option(log: Path, tmp_path: Path) -> None:
    """HCRCTL_LOG set for every command must not stop an export of that very log (export never writes it)."""
    out = tmp_path / "out.csv"
    done = run(["export", str(log), str(out)], clean_env(tmp_path, HCRCTL_LOG=str(log)))
    assert done.returncode == 0, done.stderr
    assert out.read_text().startswith("time,t,")


# -- export: written beside the target, renamed when whole -------------------------------


def broken_log(log: Path, folder: Path) -> Path:
    """``log`` with a line that is no record in the middle: the export fails half-way through."""
    lines = log.read_text().splitlines(keepends=True)
    middle = len(lines) // 2
    bad = folder / "broken.jsonl"
    bad.write_text("".join([*lines[:middle], "this is not a record\n", *lines[middle:]]))
    return bad


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_a_failed_export_leaves_the_existing_out_and_no_temporary_file(
    log: Path, tmp_path: Path, suffix: str
) -> None:
    bad = broken_log(log, tmp_path)
    out = tmp_path / f"old{suffix}"
    before, names = existing(out), listing(tmp_path)
    done = run(["export", str(bad), str(out), "--force"], clean_env(tmp_path))
    assert done.returncode != 0
    assert str(bad) in one_line(done.stderr)  # the bad line is the log's fault, said as such
    assert state(out) == before
    assert listing(tmp_path) == names


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_a_failed_export_to_a_new_out_leaves_no_file(log: Path, tmp_path: Path, suffix: str) -> None:
    bad = broken_log(log, tmp_path)
    names = listing(tmp_path)
    done = run(["export", str(bad), str(tmp_path / f"new{suffix}")], clean_env(tmp_path))
    assert done.returncode != 0
    assert str(bad) in one_line(done.stderr)
    assert listing(tmp_path) == names


def test_a_disk_that_fills_up_mid_export_keeps_the_old_out(log: Path, tmp_path: Path) -> None:
    """The error names OUT (not the temporary file), OUT is as it was, and the space is given back."""
    big = tmp_path / "big.jsonl"
    big.write_bytes(log.read_bytes() * 2000)  # its CSV is megabytes: far more than the disk holds
    with small_tmpfs(tmp_path / "small") as disk:
        out = disk / "old.csv"
        before = existing(out)
        done = run(["export", str(big), str(out), "--force"], clean_env(tmp_path))
        after, names = state(out), listing(disk)
    assert done.returncode == 1, done.stderr
    line = one_line(done.stderr)
    assert f"cannot write {out} " in line and "No space left" in line, line
    assert after == before
    assert names == [out.name]


# -- an output given as a symbolic link: refused, whatever it points at but a stream ----------

SYMLINKED = "is a symbolic link, not a file"


def symlinked(folder: Path, to_existing: bool) -> tuple[Path, Path]:
    """(link.csv, what it points at): an existing file (kept), or nothing (a dangling link)."""
    real, link = folder / "real.csv", folder / "link.csv"
    if to_existing:
        existing(real)
    link.symlink_to(real.name)
    return link, real


def outcome_of(real: Path) -> tuple[bytes, int] | None:
    return state(real) if real.exists() else None


@pytest.mark.parametrize("to_existing", [True, False], ids=["to a file", "dangling"])
@pytest.mark.parametrize("force", [False, True])
def test_export_refuses_a_symlinked_out(log: Path, tmp_path: Path, to_existing: bool, force: bool) -> None:
    link, real = symlinked(tmp_path, to_existing)
    before = outcome_of(real)
    done = run(["export", str(log), str(link), *(["--force"] if force else [])], clean_env(tmp_path))
    assert SYMLINKED in refused(done, link)
    assert outcome_of(real) == before  # not overwritten, not made
    assert link.is_symlink()


@pytest.mark.parametrize("to_existing", [True, False], ids=["to a file", "dangling"])
@pytest.mark.parametrize("force", [False, True])
def test_record_refuses_a_symlinked_out_before_the_port(
    tmp_path: Path, to_existing: bool, force: bool
) -> None:
    link, real = symlinked(tmp_path, to_existing)
    before = outcome_of(real)
    with wire() as tap:
        done = run(
            ["--port", tap.path, "record", str(link), *(["--force"] if force else [])], clean_env(tmp_path)
        )
        assert tap.read(quiet=0.3) == b""
    assert SYMLINKED in refused(done, link)
    assert outcome_of(real) == before


@pytest.mark.parametrize("to_existing", [True, False], ids=["to a file", "dangling"])
def test_a_symlinked_log_is_refused_before_the_port(tmp_path: Path, to_existing: bool) -> None:
    link, real = symlinked(tmp_path, to_existing)
    before = outcome_of(real)
    with wire() as tap:
        done = run(["--port", tap.path, "--log", str(link), "ping"], clean_env(tmp_path))
        assert tap.read(quiet=0.3) == b""
    assert SYMLINKED in refused(done, link)
    assert outcome_of(real) == before


def test_a_symlink_to_a_stream_is_written(log: Path, tmp_path: Path) -> None:
    """``/dev/null`` (a stream) holds nothing to lose: a link to it is an output like it."""
    out = tmp_path / "null.csv"
    out.symlink_to(os.devnull)
    done = run(["export", str(log), str(out)], clean_env(tmp_path))
    assert done.returncode == 0, done.stderr


# -- export, caught mid-way: its log is a FIFO the test writes ------------------------------


@pytest.fixture
def fifo(tmp_path: Path) -> Path:
    path = tmp_path / "live.jsonl"
    os.mkfifo(path)
    return path


def open_writer(path: Path, proc: subprocess.Popen[str]) -> int:
    """The FIFO's writing end, once the export has opened the reading one (ENXIO until then)."""

    def attempt() -> int | None:
        try:
            return os.open(path, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as exc:
            if exc.errno != errno.ENXIO:
                raise
        if proc.poll() is not None:  # it ended without reading its log: say why, at once
            _, err = proc.communicate()
            raise AssertionError(f"hcrctl exited {proc.returncode} before reading its log: {err!r}")
        return None

    return wait_until(attempt, what="export to open its log")


def temporaries(folder: Path) -> list[str]:
    return [name for name in os.listdir(folder) if name.startswith(".")]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_mid_export_leaves_the_out_as_it_was(
    log: Path, fifo: Path, tmp_path: Path, sig: signal.Signals
) -> None:
    out = tmp_path / "old.mcap"
    before = existing(out)
    proc = start(["export", str(fifo), str(out), "--force"], clean_env(tmp_path))
    writer = None
    try:
        writer = open_writer(fifo, proc)
        os.write(writer, log.read_bytes()[:300])  # some whole records, then half of one
        assert wait_until(lambda: temporaries(tmp_path), what="the temporary file")
        proc.send_signal(sig)
    finally:
        _, err = finish(proc)
        if writer is not None:
            os.close(writer)
    assert proc.returncode == 128 + sig, err
    assert state(out) == before
    assert temporaries(tmp_path) == []


def test_an_out_that_appears_during_the_export_is_not_replaced(log: Path, fifo: Path, tmp_path: Path) -> None:
    """Without --force the finished file takes the name only if it is still free when the export ends."""
    out = tmp_path / "new.csv"
    proc = start(["export", str(fifo), str(out)], clean_env(tmp_path))
    writer = None
    try:
        writer = open_writer(fifo, proc)
        assert wait_until(lambda: temporaries(tmp_path), what="the temporary file")
        before = existing(out)  # someone else's file, made while the export runs
        os.write(writer, log.read_bytes())
    finally:
        if writer is not None:
            os.close(writer)  # the end of the log
        _, err = finish(proc)
    assert proc.returncode == 2, err
    line = one_line(err)
    assert str(out) in line and "--force" in line
    assert state(out) == before
    assert temporaries(tmp_path) == []


# -- two writers of one file, and a FIFO no one reads ---------------------------------------


def whole(out: Path) -> int:
    """The recording is one writer's, complete: an MCAP read through its summary, a CSV of even rows.

    Returns the messages (MCAP) or rows (CSV) it holds. Two interleaved writers leave an MCAP whose
    chunks do not decompress and CSV rows cut and spliced, which fail here.
    """
    if out.suffix == ".mcap":
        from mcap.reader import make_reader

        with out.open("rb") as handle:
            reader = make_reader(handle)
            assert reader.get_summary() is not None
            return sum(1 for _ in reader.iter_messages())
    import csv

    rows = list(csv.reader(out.read_text().splitlines()))
    assert rows and rows[0][:6] == ["time", "t", "direction", "address", "command", "name"]
    assert all(len(row) == len(rows[0]) for row in rows), rows
    for row in rows[1:]:
        float(row[1])  # a spliced row has text where the seconds belong
    return len(rows) - 1


def first_ended(procs: list[subprocess.Popen[str]]) -> subprocess.Popen[str] | None:
    return next((proc for proc in procs if proc.poll() is not None), None)


def the_refusal(err: str, out: Path) -> str:
    line = one_line(err)
    assert str(out) in line and "Traceback" not in err, line
    assert "already exists" in line or "is being written by another process" in line, line
    return line


@pytest.mark.parametrize("force", [False, True])
@pytest.mark.parametrize("suffix", SUFFIXES)
def test_two_records_of_one_file_started_together_one_is_refused_the_file_whole(
    tmp_path: Path, suffix: str, force: bool
) -> None:
    """Both may pass the check for an existing file (nothing is there yet, or --force): the claim decides.

    Neither ends by itself, so they always overlap, however the machine schedules them: one
    must be refused while the other records, which then ends on Ctrl-C with its file whole.
    Started at once, a few times over, so the two often meet between the check and the first write.
    """
    out = tmp_path / f"race{suffix}"
    args = ["--port", "sim://", "record", str(out), "compass", *(["--force"] if force else [])]
    for _attempt in range(3):
        out.unlink(missing_ok=True)
        if force:
            existing(out)
        procs = [start(args, clean_env(tmp_path)) for _ in range(2)]
        try:
            refused_one = wait_until(functools.partial(first_ended, procs), what="one record to be refused")
            (recording,) = [p for p in procs if p is not refused_one]
            wait_until(lambda: out.stat().st_size > 0, what="the other to be recording")
            recording.send_signal(signal.SIGINT)
        finally:
            ended = {proc: finish(proc) for proc in procs}
        assert refused_one.returncode == 2, ended
        the_refusal(ended[refused_one][1], out)
        assert recording.returncode == 0, ended[recording]
        assert whole(out) > 0
        assert listing(tmp_path) == [out.name]


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_a_forced_record_of_a_file_being_recorded_is_refused_and_changes_nothing(
    tmp_path: Path, suffix: str
) -> None:
    out = tmp_path / f"live{suffix}"
    second = ["--port", "sim://", "record", str(out), "compass", "--duration", "0.3", "--force"]
    refusal = refused_beside_a_recording(out, clean_env(tmp_path), second, "--force")
    assert "is being written by another process" in refusal
    assert whole(out) > 0


def refused_beside_a_recording(out: Path, env: dict[str, str], args: list[str], *first: str) -> str:
    """``args`` run while a ``record`` (with ``first``) writes ``out``: its one refusal line (exit 2).

    The recording is then ended by Ctrl-C, and must end as it would alone (exit 0).
    """
    recording = start(["--port", "sim://", "record", str(out), "compass", *first], env)
    try:
        wait_until(lambda: out.exists() and out.stat().st_size > 0, what="the recording to begin")
        other = run(args, env)  # one that took the file would write on: the run's timeout fails the test
        assert other.returncode == 2, other.stderr
        refusal = the_refusal(other.stderr, out)
        recording.send_signal(signal.SIGINT)
    finally:
        _, err = finish(recording)
    assert recording.returncode == 0, err
    return refusal


def test_a_forced_export_over_a_file_being_recorded_is_refused(log: Path, tmp_path: Path) -> None:
    """Renaming over a live recording would leave its writer writing to a file that has gone."""
    out = tmp_path / "live.csv"
    refusal = refused_beside_a_recording(out, clean_env(tmp_path), ["export", str(log), str(out), "--force"])
    assert "is being written by another process" in refusal
    assert temporaries(tmp_path) == []
    assert whole(out) > 0


@pytest.mark.parametrize("which", ["OUT", "--log"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_record_to_a_fifo_no_one_reads_ends_on_a_signal(
    tmp_path: Path, sig: signal.Signals, which: str
) -> None:
    """A blocked open() is resumed after a signal whose handler only sets record's stop flag: it is not blocked."""
    fifo = tmp_path / ("pipe.csv" if which == "OUT" else "pipe.jsonl")
    os.mkfifo(fifo)
    out = fifo if which == "OUT" else tmp_path / "out.csv"
    with wire() as tap:
        args = [
            "--port",
            tap.path,
            *(["--log", str(fifo)] if which == "--log" else []),
            "record",
            str(out),
            "compass",
        ]
        proc = start(args, clean_env(tmp_path))
        try:
            said = stderr_until(proc, "(a FIFO)\n")
            proc.send_signal(sig)
        finally:
            _, err = finish(proc)
        assert tap.read(quiet=0.3) == b""  # it never got as far as the port
    assert proc.returncode == 128 + sig, said + err
    assert said.strip() == f"hcrctl: waiting for a reader of {which} {fifo} (a FIFO)"
    assert "Traceback" not in err
    assert listing(tmp_path) == [fifo.name]  # no empty OUT left behind


def test_a_record_to_a_fifo_writes_once_a_reader_comes(tmp_path: Path) -> None:
    out = tmp_path / "pipe.csv"
    os.mkfifo(out)
    proc = start(
        ["--port", "sim://", "record", str(out), "compass", "--duration", "0.5"], clean_env(tmp_path)
    )
    try:
        stderr_until(proc, "(a FIFO)\n")
        with out.open("rb") as reader:
            got = reader.read()
    finally:
        _, err = finish(proc)
    assert proc.returncode == 0, err
    assert got.startswith(b"time,t,direction,address,command,name,") and b",compass," in got


def test_a_forced_bridge_mcap_of_a_file_being_recorded_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "live.mcap"
    args = ["--port", "sim://", "bridge", "--listen", "127.0.0.1:0", "--mcap", str(out), "--force"]
    assert "--mcap" in refused_beside_a_recording(out, clean_env(tmp_path), args)
    assert whole(out) > 0
