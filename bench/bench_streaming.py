"""Issue 15: whole-file work as ratios against plain Python references, at two input sizes.

Run from the repository root: ``python bench/bench_streaming.py [--root CHECKOUT]``. ``--root``
times another checkout's hcrctl (``python -m hcrctl`` with PYTHONPATH=CHECKOUT), for a before/after
table. Every hcrctl run and its reference run on the same files in turns (best of ``--repeat``);
peak memory is the child's ru_maxrss from wait4. Writes ``bench/results/streaming.json``.

Children run as a user runs them: stdout buffered (PYTHONUNBUFFERED removed: it costs the
references a system call per line) and bytecode cached (PYTHONDONTWRITEBYTECODE removed; the
caches go to a temporary PYTHONPYCACHEPREFIX, written by one untimed run of each command, so no
checkout is touched). ``--env-as-is`` keeps the environment as inherited instead.

Two kinds of input. hcrctl's own (``own_*``): a ``--log`` written by ``hcrctl --port
'sim://?wander=1' --log LOG --json watch --rate max`` (requests, replies and the stations'
broadcasts, as a session logs them), and a capture of the same bytes, the log's ``hex`` in order
(repeated to the size); and the random mix of ``bench_decoder.mixed_stream`` (``view_*``,
``summary_*``, ``monitor_*``: most of its frames are distinct, the worst case for a view).

- ``hex decode --file`` (and ``--json``) to a file vs ``ref_framer.py`` (bytes.find, one line per frame): 1 and 4 MiB;
- ``hex decode --summary --file`` vs ``ref_framer.py --count``;
- 1 and 2 MiB of ``55 AA``: time and peak memory;
- ``monitor --from`` a log of 25,000 and 100,000 records vs a json.loads loop printing one line each;
- replay's log: tracemalloc peak while reading 2,000 and 20,000 tx records twice (two passes).

Each ratio is printed beside its bound (``TARGETS``); the script exits 1 if one is missed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import tracemalloc
from pathlib import Path

from _common import ROOT, record
from bench_decoder import mixed_stream

from hcrctl.protocol.frames import HEADER, encode

HERE = Path(__file__).resolve().parent
REF_LOG = """
import json, sys
for line in open(sys.argv[1], encoding="utf-8"):
    rec = json.loads(line)
    sys.stdout.write(f"{rec['time']}  {rec['direction']}  {rec['hex']}\\n")
"""


#: Runs argv[2:] from a fresh, small interpreter and writes its peak RSS (KiB) and wall seconds to
#: argv[1]: Linux counts a child's memory from before exec in ru_maxrss, so forking from this (large)
#: process directly would report this process's size. The time runs from the fork to the child's
#: end, so the trampoline's own start-up is counted for neither side.
TRAMPOLINE = """
import os, sys, time
start = time.perf_counter()
pid = os.fork()
if pid == 0:
    os.execv(sys.argv[2], sys.argv[2:])
_, status, usage = os.wait4(pid, 0)
cpu = usage.ru_utime + usage.ru_stime
open(sys.argv[1], "w").write(f"{usage.ru_maxrss} {time.perf_counter() - start} {cpu}")
"""

#: Time the children by their CPU time (user + system) instead of the wall clock (``--cpu``): on a
#: machine so loaded that wall times are noise.
CLOCK = {"cpu": 0}


def timed(args: list[str], env: dict[str, str], out: str = os.devnull) -> tuple[float, int]:
    """Wall seconds and peak RSS (KiB) of one child run, its stdout to ``out``."""
    report = Path(tempfile.gettempdir()) / f"bench15-rss-{os.getpid()}"
    with open(out, "wb") as sink:
        subprocess.run(
            [sys.executable, "-c", TRAMPOLINE, str(report), *args],
            stdout=sink,
            stderr=subprocess.DEVNULL,
            env=env,
            cwd=env["PYTHONPATH"],  # ``python -m`` looks in the working directory before PYTHONPATH
        )
        rss, wall, cpu = report.read_text().split()
        return float(cpu if CLOCK["cpu"] else wall), int(rss)


def best(runs: dict[str, list[str]], env: dict[str, str], repeat: int) -> dict[str, tuple[float, int]]:
    """Best time and the peak RSS of each command, taken in turns (after one untimed run of each)."""
    out: dict[str, tuple[float, int]] = {name: (1e9, 0) for name in runs}
    for args in runs.values():
        timed(args, env)  # bytecode caches written, files in the page cache
    for _ in range(repeat):
        for name, args in runs.items():
            seconds, rss = timed(args, env, out=str(Path(tempfile.gettempdir()) / f"bench15-{name}.out"))
            out[name] = (min(out[name][0], seconds), max(out[name][1], rss))
    return out


def write_log(path: Path, records: int) -> None:
    frames = [encode(1, 0x14, b"\x0d\x0a"), encode(1, 0x14, b"\xff"), encode(0x50, 0xA0, b"\x01\x02\x03\x04")]
    with open(path, "w") as out:
        for n in range(records):
            frame = frames[n % 3]
            direction = "tx" if n % 3 == 1 else "rx"
            out.write(
                f'{{"time": "2026-01-01T00:{n // 60000 % 60:02d}:{n // 1000 % 60:02d}.{n % 1000:03d}000", '
                f'"direction": "{direction}", "hex": "{frame.hex(" ").upper()}"}}\n'
            )


def own_log(path: Path, records: int, env: dict[str, str]) -> None:
    """A ``--log`` of ``records`` lines written by hcrctl itself: a wandering simulated robot's
    sensors read as fast as they answer, with the stations' broadcasts (the first ``records``)."""
    whole = path.with_suffix(".all")
    seconds = 4.0
    while True:
        whole.unlink(missing_ok=True)
        args = ["--port", "sim://?wander=1", "--log", str(whole), "--json", "watch", "--rate", "max"]
        subprocess.run(
            [sys.executable, "-m", "hcrctl", *args, "--duration", str(seconds)],
            stdout=subprocess.DEVNULL,
            env=env,
            cwd=env["PYTHONPATH"],
            check=True,
        )
        with open(whole, "rb") as log:
            lines = log.readlines()
        if len(lines) >= records:
            path.write_bytes(b"".join(lines[:records]))
            whole.unlink()
            return
        seconds *= 2 * records / max(len(lines), 1)


def own_capture(log: Path, size: int) -> bytes:
    """The bytes of ``log`` (its records' ``hex``) in order, repeated to ``size`` bytes."""
    import json

    with open(log, encoding="utf-8") as lines:
        data = b"".join(bytes.fromhex(json.loads(line)["hex"]) for line in lines)
    return (data * (size // len(data) + 1))[:size]


def replay_peak(path: Path, hcrctl_root: Path) -> int:
    sys.path.insert(0, str(hcrctl_root))
    for name in [m for m in sys.modules if m.startswith("hcrctl")]:
        del sys.modules[name]
    from hcrctl.ops.replay import tx_records

    tracemalloc.start()
    log = tx_records(str(path))
    for _ in range(2):
        for _rec in log:
            pass
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    sys.path.remove(str(hcrctl_root))
    return peak


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=ROOT, help="the checkout whose hcrctl is timed")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--name", default="streaming")
    parser.add_argument(
        "--no-summary", action="store_true", help="for a checkout without hex decode --summary"
    )
    parser.add_argument(
        "--env-as-is", action="store_true", help="keep PYTHONUNBUFFERED and friends as inherited"
    )
    parser.add_argument("--cpu", action="store_true", help="time by the children's CPU time, not the wall")
    args = parser.parse_args(argv)
    CLOCK["cpu"] = int(args.cpu)
    work = Path(tempfile.mkdtemp(prefix="bench15-"))
    env = dict(os.environ, PYTHONPATH=str(args.root), COLUMNS="120")
    if not args.env_as_is:
        env.pop("PYTHONUNBUFFERED", None)
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(work / "pycache")
    try:
        return _run(args, env, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _run(args: argparse.Namespace, env: dict[str, str], work: Path) -> int:
    hcrctl = [sys.executable, "-m", "hcrctl"]
    py = [sys.executable]
    metrics: dict[str, object] = {"root": str(args.root), "env_as_is": args.env_as_is, "cpu": args.cpu}
    own = work / "own.jsonl"
    own_log(own, 100_000, env)
    inputs = [(f"own_{mib}MiB", mib, own_capture(own, mib << 20)) for mib in (1, 4)]
    inputs += [(f"{mib}MiB", mib, mixed_stream(frames)) for mib, frames in ((1, 90_000), (4, 360_000))]
    for name, mib, data in inputs:
        cap = work / f"cap{name}.bin"
        cap.write_bytes(data)
        prefix = "own_" if name.startswith("own_") else ""
        size = f"{mib}MiB"
        got = best(
            {
                "view": [*hcrctl, "hex", "decode", "--file", str(cap)],
                "json": [*hcrctl, "hex", "decode", "--json", "--file", str(cap)],
                "ref": [*py, str(HERE / "ref_framer.py"), str(cap)],
            },
            env,
            args.repeat,
        )
        metrics[f"{prefix}view_{size}"] = _pair(got, "view", "ref")
        metrics[f"{prefix}view_json_{size}"] = _pair(got, "json", "ref")
        if not args.no_summary:
            got = best(
                {
                    "summary": [*hcrctl, "hex", "decode", "--summary", "--file", str(cap)],
                    "count": [*py, str(HERE / "ref_framer.py"), str(cap), "--count"],
                },
                env,
                args.repeat,
            )
            metrics[f"{prefix}summary_{size}"] = _pair(got, "summary", "count")
    for mib in (1, 2):
        junk = work / f"55aa{mib}.bin"
        junk.write_bytes(HEADER * (mib << 19))
        got = best({"55aa": [*hcrctl, "hex", "decode", "--file", str(junk)]}, env, 1)
        metrics[f"55aa_{mib}MiB"] = {
            "s": round(got["55aa"][0], 2),
            "rss_mib": round(got["55aa"][1] / 1024, 1),
        }
    logs = [("own_monitor_100000", own)]
    for records in (25_000, 100_000):
        log = work / f"log{records}.jsonl"
        write_log(log, records)
        logs.append((f"monitor_{records}", log))
    for key, log in logs:
        got = best(
            {
                "monitor": [*hcrctl, "monitor", "--from", str(log)],
                "json": [*hcrctl, "--json", "monitor", "--from", str(log)],
                "ref": [*py, "-c", REF_LOG, str(log)],
            },
            env,
            args.repeat,
        )
        metrics[key] = _pair(got, "monitor", "ref")
        metrics[key.replace("monitor", "monitor_json")] = _pair(got, "json", "ref")
    for records in (2_000, 20_000):
        log = work / f"tx{records}.jsonl"
        write_log(log, records)
        metrics[f"replay_log_peak_{records}"] = replay_peak(log, args.root)
    for key, value in metrics.items():
        print(f"  {key}: {value}")
    record(args.name, metrics)
    missed = 0
    print(f"load average {os.getloadavg()[0]:.1f}")
    for key, target in TARGETS.items():
        value = metrics.get(key)
        if isinstance(value, dict):
            ok = value["ratio"] <= target
            missed += not ok
            print(
                f"  {'ok  ' if ok else 'MISS'} {key}: {value['ratio']:.2f}x the reference (bound {target}x)"
            )
    return 1 if missed else 0


#: The time bounds, as ratios to the reference measured in the same run: ``hex decode``'s 1.5x and
#: ``--summary``'s 0.5x hold on hcrctl's own inputs (``own_*``) and on the random mix alike; its JSON
#: and ``monitor --from`` of the synthetic log keep their earlier 2x.
TARGETS = {
    "own_view_1MiB": 1.5,
    "own_view_4MiB": 1.5,
    "own_summary_4MiB": 0.5,
    "own_monitor_100000": 1.5,
    "view_1MiB": 1.5,
    "view_4MiB": 1.5,
    "view_json_1MiB": 2.0,
    "view_json_4MiB": 2.0,
    "summary_4MiB": 0.5,
    "monitor_25000": 2.0,
    "monitor_100000": 2.0,
}


def _pair(got: dict[str, tuple[float, int]], ours: str, ref: str) -> dict[str, float]:
    return {
        "s": round(got[ours][0], 2),
        "ref_s": round(got[ref][0], 2),
        "ratio": round(got[ours][0] / got[ref][0], 2),
        "rss_mib": round(got[ours][1] / 1024, 1),
        "ref_rss_mib": round(got[ref][1] / 1024, 1),
    }


if __name__ == "__main__":
    sys.exit(main())
