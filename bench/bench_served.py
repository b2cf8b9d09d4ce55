"""What serving one robot costs: ``fleet serve`` at 10 Hz, CPU as % of one core and RSS, beside the bridge.

Run from the repository root: ``python bench/bench_served.py [--seconds 20] [--rounds 3] [--source DIR]``.

Each round starts a Zenoh router and, at the same time, every process
measured, each polling its own ``hcrctl sim --pty`` at 10 Hz (the simulator
in a process of its own, so the figure is the server's alone):

- ``fleet serve`` (the target: <= 2 % of one core, <= 30 MB RSS);
- ``fleet serve`` on ``sim://`` (the simulator inside the serve, as
  ``bench_fleet.py`` measures it);
- ``bridge --rate 10`` with no client: the baseline, the same served-robot
  runtime without Zenoh;
- with ``--source DIR``, ``fleet serve`` from that checkout (another
  commit, e.g. ``git archive main | tar -x -C DIR``), the before beside the after.

Then, ``--ends`` times: a ``fleet serve`` whose port went away while the
robot stood still (driven by a one-shot ``drive power 30 30 --for 0.3``
over ``zenoh://``, which ends with its stop delivered) gets SIGTERM; the figure is the time to
its exit (target: within 1 s), its exit status and whether it raised the
"may still be moving" alarm, beside the ``--source`` tree's, given
``--stop-wait 5`` so that one waits 5 s, not 30.

Every process is started as ``python -m hcrctl`` with ``PYTHONPATH`` set
to its checkout, so both trees start alike. After ``--warmup`` seconds, CPU
is utime + stime over ``--seconds`` (``/proc/PID/stat``), and memory is read
at the end from ``/proc/PID/smaps_rollup``: RSS (the target), PSS (shared
pages divided among the processes mapping them: what each of N robots on
one machine costs) and USS (private pages). The figures are the medians
over rounds, and the load average is printed beside them. Writes ``bench/results/bench_served.json``; exits 1
if a target is missed. Needs the zenoh extra (and foxglove for the bridge).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from _common import ROOT, TICK, cpu_ticks, free_endpoint, kill_groups, record

CPU_TARGET = 2.0
RSS_TARGET = 30.0


class Procs:
    """Children in sessions of their own, stderr to files; every one killed on exit."""

    def __init__(self, tmp: Path) -> None:
        self.tmp, self.all, self._n = tmp, [], 0

    def start(
        self, *args: str, root: Path = ROOT, stdout: int = subprocess.DEVNULL
    ) -> subprocess.Popen[bytes]:
        self._n += 1
        env = dict(os.environ, PYTHONPATH=str(root), HOME=str(self.tmp))
        with (self.tmp / f"{self._n}.err").open("wb") as stderr:
            proc = subprocess.Popen(
                [sys.executable, "-m", "hcrctl", *args],
                stdin=subprocess.DEVNULL,
                stdout=stdout,
                stderr=stderr,
                env=env,
                cwd=self.tmp,  # python -m puts the working directory first: no checkout there
                start_new_session=True,
            )
        proc.err = self.tmp / f"{self._n}.err"  # type: ignore[attr-defined]
        self.all.append(proc)
        return proc

    def pty(self) -> str:
        """A simulator on a pty of its own: its path."""
        proc = self.start("sim", "--pty", stdout=subprocess.PIPE)
        assert proc.stdout is not None
        return proc.stdout.readline().decode().strip()

    def close(self) -> None:
        kill_groups(self.all)


@contextlib.contextmanager
def procs() -> Iterator[Procs]:
    with tempfile.TemporaryDirectory(prefix="bench-served-") as tmp:
        group = Procs(Path(tmp))
        try:
            yield group
        finally:
            group.close()


def wait_said(proc: subprocess.Popen[bytes], text: str, timeout: float = 60.0) -> None:
    err: Path = proc.err  # type: ignore[attr-defined]
    deadline = time.monotonic() + timeout
    while text not in err.read_text():
        if proc.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"never said {text!r}: {err.read_text()!r}")
        time.sleep(0.05)


def memory_mb(pid: int) -> tuple[float, float, float]:
    """(RSS, PSS, USS) in MB: all resident pages; shared ones divided among their users; private ones."""
    found: dict[str, int] = {}
    for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
        name, _, rest = line.partition(":")
        if rest.strip().endswith("kB"):
            found[name] = int(rest.split()[0])
    private = found.get("Private_Clean", 0) + found.get("Private_Dirty", 0)
    return found.get("Rss", 0) / 1024, found.get("Pss", 0) / 1024, private / 1024


Figures = dict[str, tuple[float, float, float, float]]


def one_round(seconds: float, warmup: float, source: Path | None) -> Figures:
    """{label: (CPU % of one core, RSS, PSS, USS in MB)} of every process measured, side by side."""
    with procs() as group:
        endpoint = free_endpoint()
        group.start("fleet", "router", "--listen", endpoint)
        zenoh = ("--zenoh", endpoint)
        started = {
            "fleet serve": group.start("--port", group.pty(), *zenoh, "fleet", "serve", "r1", "--rate", "10"),
            "fleet serve sim://": group.start(
                "--port", "sim://", *zenoh, "fleet", "serve", "r2", "--rate", "10"
            ),
            "bridge (baseline)": group.start(
                "--port", group.pty(), "bridge", "--listen", "127.0.0.1:0", "--rate", "10"
            ),
        }
        if source is not None:
            started["fleet serve (--source)"] = group.start(
                "--port", group.pty(), *zenoh, "fleet", "serve", "r3", "--rate", "10", root=source
            )
        for proc in started.values():
            wait_said(proc, "serving ")
        time.sleep(warmup)
        before = {label: cpu_ticks(p.pid) for label, p in started.items()}
        start = time.monotonic()
        time.sleep(seconds)
        wall = time.monotonic() - start
        return {
            label: ((cpu_ticks(p.pid) - before[label]) / TICK / wall * 100, *memory_mb(p.pid))
            for label, p in started.items()
        }


ALARM = "may still be moving"


def sigterm_end(root: Path) -> tuple[float, int, bool]:
    """(seconds from SIGTERM to exit, exit status, alarm said) of a serve whose port went away while still."""
    with procs() as group:
        endpoint = free_endpoint()
        group.start("fleet", "router", "--listen", endpoint)
        sim = group.start("sim", "--pty", stdout=subprocess.PIPE)
        assert sim.stdout is not None
        port = sim.stdout.readline().decode().strip()
        serve = group.start(
            "--stop-wait", "5", "--port", port, "--zenoh", endpoint, "fleet", "serve", "r1", root=root
        )
        wait_said(serve, "serving ")
        drive = group.start(  # the operator from the same tree: the fleet's contract may differ between trees
            "--zenoh",
            endpoint,
            "--port",
            "zenoh://r1",
            "drive",
            "power",
            "30",
            "30",
            "--for",
            "0.3",
            root=root,
        )
        if drive.wait(timeout=60) != 0:  # the one-shot ends with stop delivered: the robot stands still
            raise RuntimeError(f"the drive failed: {drive.err.read_text()!r}")  # type: ignore[attr-defined]
        sim.kill()
        wait_said(serve, "went away")
        start = time.monotonic()
        serve.send_signal(signal.SIGTERM)
        status = serve.wait(timeout=60)
        took = time.monotonic() - start
        return took, status, ALARM in serve.err.read_text()  # type: ignore[attr-defined]


def part_ends(rounds: int, source: Path | None, metrics: dict[str, float]) -> bool:
    trees = {"fleet serve": ROOT, **({"fleet serve (--source)": source} if source else {})}
    ok = True
    for label, root in trees.items():
        ends = [sigterm_end(root) for _ in range(rounds)]
        took = [t for t, _, _ in ends]
        print(
            f"{label}: SIGTERM to exit {min(took):.2f}-{max(took):.2f} s, statuses {sorted({s for _, s, _ in ends})}, "
            f"alarm in {sum(a for _, _, a in ends)} of {rounds}"
        )
        metrics[f"{label} sigterm_s_max"] = round(max(took), 2)
        metrics[f"{label} alarms"] = sum(a for _, _, a in ends)
        if label == "fleet serve":
            ok = max(took) <= 1.0 and not any(a for _, _, a in ends) and all(s == 0 for _, s, _ in ends)
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--warmup", type=float, default=3.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--source", type=Path, help="another checkout's fleet serve, measured beside")
    parser.add_argument("--ends", type=int, default=5, help="rounds of SIGTERM with the port gone (0 skips)")
    args = parser.parse_args()
    rounds = []
    for n in range(args.rounds):
        figures = one_round(args.seconds, args.warmup, args.source)
        load = os.getloadavg()[0]
        shown = ", ".join(
            f"{k} {cpu:.2f} % / RSS {rss:.1f} PSS {pss:.1f} USS {uss:.1f} MB"
            for k, (cpu, rss, pss, uss) in figures.items()
        )
        print(f"round {n + 1} (load {load:.1f}): {shown}")
        rounds.append(figures)
    metrics: dict[str, float] = {}
    for label in rounds[0]:
        for i, what in enumerate(("cpu_pct", "rss_mb", "pss_mb", "uss_mb")):
            metrics[f"{label} {what}"] = round(statistics.median(r[label][i] for r in rounds), 2)
    serve_cpu, serve_rss = metrics["fleet serve cpu_pct"], metrics["fleet serve rss_mb"]
    metrics["fleet serve / bridge cpu"] = round(
        serve_cpu / max(metrics["bridge (baseline) cpu_pct"], 1e-9), 2
    )
    ends_ok = part_ends(args.ends, args.source, metrics) if args.ends else True
    metrics["load"] = round(os.getloadavg()[0], 1)
    record("bench_served", metrics)
    ok = serve_cpu <= CPU_TARGET and serve_rss <= RSS_TARGET and ends_ok
    print(f"  {'ok  ' if ends_ok else 'MISS'} SIGTERM with the port gone while still: within 1 s, no alarm")
    print(
        f"  {'ok  ' if serve_cpu <= CPU_TARGET else 'MISS'} fleet serve CPU {serve_cpu:.2f} % (target <= {CPU_TARGET})"
    )
    print(
        f"  {'ok  ' if serve_rss <= RSS_TARGET else 'MISS'} fleet serve RSS {serve_rss:.1f} MB (target <= {RSS_TARGET})"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
