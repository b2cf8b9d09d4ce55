"""Session churn: what a peer cycling throw-away operator sessions costs a ``fleet serve``'s memory.

Run from the repository root: ``python bench/bench_fleet_churn.py [--sessions 3000] [--source DIR]``.

For each tree (this checkout, and with ``--source DIR`` another one, e.g.
``git archive HEAD | tar -x -C DIR``, side by side in the same run) a Zenoh
router and ``fleet serve r1`` on ``sim://`` start, and a churner in this
process cycles ``--sessions`` sessions as fast as the serve answers, each
the way a peer would: a fresh key pair, its liveliness token, the ask for its
lease value, a signed claim naming its key (so the robot side remembers the
session, its key and numbers), the token undeclared. The serve's RSS
(``/proc/PID/status`` VmRSS, after 2 s of quiet) is read before the churn
and after it: the figure is the growth in MB and the after/before ratio, the
baseline being the same process before its churn, beside the other tree's.
Also printed: how many sessions were admitted (granted a lease value) and how
many were told to wait their turn, and the churn's rate. Targets: RSS after
at most 1.25x before (3000 sessions, the default), and with ``--source`` a
growth at most half the other tree's in the same run. ``--no-claims``: the
sessions only come and go (no key named), to tell what a claim costs. Writes
``bench/results/bench_fleet_churn.json``; exits 1 if the target is missed.
Needs the zenoh extra.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from _common import ROOT, free_endpoint, kill_groups, record

RSS_RATIO_TARGET = 1.25
#: This tree's RSS growth against the ``--source`` tree's, through the same churn.
GROWTH_VS_SOURCE_TARGET = 0.5


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS")


def start(tmp: Path, root: Path, label: str, *args: str) -> subprocess.Popen[bytes]:
    env = dict(os.environ, PYTHONPATH=str(root), HOME=str(tmp), XDG_DATA_HOME=str(tmp / "data"))
    err = (tmp / f"{label}.err").open("wb")
    return subprocess.Popen(
        [sys.executable, "-m", "hcrctl", *args],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=err,
        env=env,
        cwd=tmp,
        start_new_session=True,
    )


def wait_err(path: Path, text: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while text not in (path.read_text() if path.exists() else ""):
        if time.monotonic() > deadline:
            raise SystemExit(f"never said {text!r}: {path.read_text()[-500:]}")
        time.sleep(0.05)


def client(endpoint: str) -> Any:
    import zenoh

    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
    cfg.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(cfg)


def ask(s: Any, key: str, payload: bytes, attachment: bytes | None = None) -> tuple[bool, dict[str, Any]]:
    for reply in s.get(key, payload=payload, attachment=attachment, timeout=5.0):
        ok = reply.ok is not None
        return ok, json.loads((reply.ok if ok else reply.err).payload.to_bytes())
    return False, {}


def one_session(s: Any, challenge: str, n: int, claims: bool = True) -> str:
    """One throw-away session: ``admitted``, ``waited`` (told to wait its turn) or ``unadmitted``."""
    from hcrctl.link.zenoh import identity, keyspace

    me = identity.Identity()
    op = keyspace.Who(f"churn{n % 7}", me.session)
    token = s.liveliness().declare_token(keyspace.operator("r1", op.name, op.session))
    try:
        asked = json.dumps({"op": op.name, "session": op.session, "do": "lease"}).encode()
        for _ in range(100):  # the token on its way
            ok, answer = ask(s, keyspace.drive("r1"), asked)
            if ok or answer.get("token") is not False:
                break
            time.sleep(0.002)
        if not ok:
            return "waited" if answer.get("waiting") else "unadmitted"
        if not claims:
            return "admitted"
        claim = json.dumps(
            {"op": op.name, "session": op.session, "do": "claim", "key": me.public_hex}
        ).encode()
        signed = identity.signed_bytes(challenge, answer["lease"], "r1", "claim", op, 1, claim)
        ask(s, keyspace.drive("r1"), claim, keyspace.attachment(op, 1, me.sign(signed)))
        asked = json.dumps({"op": op.name, "session": op.session, "do": "release"}).encode()
        signed = identity.signed_bytes(challenge, answer["lease"], "r1", "release", op, 2, asked)
        ask(s, keyspace.drive("r1"), asked, keyspace.attachment(op, 2, me.sign(signed)))
        return "admitted"
    finally:
        token.undeclare()


def churn(root: Path, sessions: int, claims: bool) -> dict[str, float]:
    with tempfile.TemporaryDirectory(prefix="hcrctl-churn-") as name:
        tmp = Path(name)
        endpoint = free_endpoint()
        procs = [start(tmp, root, "router", "--zenoh", endpoint, "fleet", "router")]
        try:
            procs.append(
                start(tmp, root, "r1", "--zenoh", endpoint, "--port", "sim://", "fleet", "serve", "r1")
            )
            wait_err(tmp / "r1.err", "serving r1")
            s = client(endpoint)
            _, info = ask(s, "hcr/r1/info", b"{}")
            one_session(s, info["challenge"], -1)  # what any first operator loads (the signatures' library)
            time.sleep(2.0)
            before = rss_mb(procs[1].pid)
            counts: dict[str, int] = {"admitted": 0, "waited": 0, "unadmitted": 0}
            started = time.monotonic()
            for n in range(sessions):
                counts[one_session(s, info["challenge"], n, claims)] += 1
            took = time.monotonic() - started
            time.sleep(2.0)
            after = rss_mb(procs[1].pid)
            s.close()
        finally:
            kill_groups(procs)
    return {
        "rss_before_mb": before,
        "rss_after_mb": after,
        "growth_mb": after - before,
        "ratio": after / before,
        "sessions_per_s": sessions / took,
        **{k: float(v) for k, v in counts.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--sessions", type=int, default=3000)
    parser.add_argument("--no-claims", dest="claims", action="store_false")
    parser.add_argument("--source", type=Path, help="another checkout, measured the same way beside this one")
    args = parser.parse_args()
    trees = {"this": ROOT} | ({"source": args.source.resolve()} if args.source else {})
    metrics: dict[str, float] = {}
    for label, root in trees.items():
        for key, value in churn(root, args.sessions, args.claims).items():
            metrics[f"{label}_{key}"] = round(value, 2)
    load = os.getloadavg()[0]
    metrics["load"] = round(load, 1)
    record("bench_fleet_churn", metrics)
    ok = verdict("RSS after/before", metrics["this_ratio"], RSS_RATIO_TARGET)
    if "source_growth_mb" in metrics:
        versus = metrics["this_growth_mb"] / max(metrics["source_growth_mb"], 0.01)
        ok = verdict("RSS growth against --source's", versus, GROWTH_VS_SOURCE_TARGET) and ok
    sys.exit(0 if ok else 1)


def verdict(label: str, value: float, target: float) -> bool:
    ok = value <= target
    print(f"  {'ok  ' if ok else 'MISS'} {label}: {value:.2f} (target <= {target})", flush=True)
    return ok


if __name__ == "__main__":
    main()
