"""A fleet client written from docs/fleet.md's "Writing a client" alone: a raw Zenoh session and pyca's
cryptography, nothing of hcrctl. Run as a program (on any host of a test's topology); it prints one JSON
object a line for the test to read.

    python fleet_raw_client.py ENDPOINT ROBOT drive        list, read, claim, drive, stop, release
    python fleet_raw_client.py ENDPOINT ROBOT stranger     claim and drive under another's listed session
    python fleet_raw_client.py ENDPOINT ROBOT capture FILE a signed claim granted and a motion, saved to FILE
    python fleet_raw_client.py ENDPOINT ROBOT churn N       N sessions that claim, release and go
    python fleet_raw_client.py ENDPOINT ROBOT replay FILE  that claim and motion sent again, under a copy
                                                           of its token
    python fleet_raw_client.py ENDPOINT ROBOT copy [KEYEXPR]  copy every operator token (and subscribe to
                                                           KEYEXPR), hold them until killed
"""

from __future__ import annotations

import hashlib
import json
import secrets
import sys
import threading
import time
from typing import Any

import zenoh
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

WAIT_S = 10.0
#: Step 6's renewal period, as docs/fleet.md gives hcrctl's (a moving driver silent 0.25 s is gone).
RENEW_S = 0.05


def say(**fields: Any) -> None:
    print(json.dumps(fields), flush=True)


def open_session(endpoint: str) -> Any:
    """Step 1: client mode, the router's endpoint, scouting off, the fleet's 3 s link lease."""
    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
    cfg.insert_json5("scouting/multicast/enabled", "false")
    cfg.insert_json5("scouting/gossip/enabled", "false")
    cfg.insert_json5("transport/link/tx/lease", "3000")
    return zenoh.open(cfg)


class Client:
    """One operator session: its key pair, its token, its numbered and signed messages."""

    def __init__(self, session: Any, robot: str, name: str, private: Ed25519PrivateKey | None = None) -> None:
        self.s, self.robot, self.name = session, robot, name
        self.private = private or Ed25519PrivateKey.generate()
        raw = self.private.public_key().public_bytes_raw()
        self.key = raw.hex()  # step 2: 64 lower-case hex digits
        self.session = hashlib.sha256(raw).hexdigest()[:16]
        self.seq = 0
        self.challenge = ""
        self.lease = ""
        self.token: Any = None

    def declare(self) -> None:
        self.token = self.s.liveliness().declare_token(f"hcr/{self.robot}/op/{self.name}/{self.session}")

    def info(self) -> dict[str, Any]:
        """Step 3: the robot's info, with the challenge every signature covers, believed only when signed for
        this question by the robot key it names."""
        nonce = secrets.token_hex(16)
        key = f"hcr/{self.robot}/info"
        for reply in self.s.get(key, payload=json.dumps({"nonce": nonce}), timeout=WAIT_S):
            data = reply.ok.payload.to_bytes()
            info: dict[str, Any] = json.loads(data)
            if not proven(info.get("key", ""), key, nonce, data):
                raise SystemExit("the info is not signed by the robot key it names")
            self.challenge = info.get("challenge", "")  # an older serve has none: its failure is the test's
            return info
        raise SystemExit("no info")

    def admit(self) -> dict[str, Any]:
        """Step 4: the lease value the robot side drew when it admitted this session, asked again while
        the answer says the token is not there yet; the last answer."""
        deadline = time.monotonic() + WAIT_S
        while True:
            asked = json.dumps({"op": self.name, "session": self.session, "do": "lease"}).encode()
            ok, answer = self.send(f"hcr/{self.robot}/drive", asked, None)
            if ok:
                self.lease = answer["lease"]
            if ok or answer.get("token") is not False or time.monotonic() > deadline:
                return answer
            time.sleep(0.05)

    def attachment(self, what: str, payload: bytes, seq: int | None = None) -> bytes:
        """``OP SESSION SEQ SIGNATURE``, signed over the head lines and the payload as sent."""
        if seq is None:
            self.seq += 1
            seq = self.seq
        head = (
            f"hcr-fleet-2\n{self.challenge}\n{self.lease}\n{self.robot}\n{what}\n"
            f"{self.name}\n{self.session}\n{seq}\n"
        )
        signature = self.private.sign(head.encode("ascii") + payload).hex()
        return f"{self.name} {self.session} {seq} {signature}".encode("ascii")

    def ask(self, key: str, message: dict[str, Any], what: str) -> tuple[bool, dict[str, Any], bytes, bytes]:
        """A signed query: (ok, the answer, the payload and attachment sent)."""
        payload = json.dumps(message).encode()
        attachment = self.attachment(what, payload)
        return (*self.send(key, payload, attachment), payload, attachment)

    def send(self, key: str, payload: bytes, attachment: bytes | None) -> tuple[bool, dict[str, Any]]:
        """A query's answer, its signature left out (what it proves is checked on the info, step 3)."""
        for reply in self.s.get(key, payload=payload, attachment=attachment, timeout=WAIT_S):
            ok = reply.ok is not None
            answer: dict[str, Any] = json.loads((reply.ok if ok else reply.err).payload.to_bytes())
            answer.pop("signature", None)
            return ok, answer
        return False, {"error": "no answer"}

    def claim(self) -> tuple[bool, dict[str, Any], bytes, bytes]:
        """Step 5: a claim naming the key, asked again while the answer says the token is not there yet."""
        if not self.lease:
            self.admit()
        deadline = time.monotonic() + WAIT_S
        while True:
            message = {"op": self.name, "session": self.session, "do": "claim", "key": self.key}
            found = self.ask(f"hcr/{self.robot}/drive", message, "claim")
            if found[0] or found[1].get("token") is not False or time.monotonic() > deadline:
                return found
            time.sleep(0.05)

    def put(self, key: str, message: dict[str, Any], what: str) -> None:
        payload = json.dumps(message).encode()
        self.s.put(key, payload, attachment=self.attachment(what, payload))


def proven(public: str, key: str, nonce: str, data: bytes) -> bool:
    """Whether ``data`` (an answer on ``key``) is signed by the robot key ``public`` for ``nonce``: its last
    member ``, "signature": "HEX"`` taken out, the rest is what was signed, after the head lines."""
    tail = b', "signature": "'
    at = data.rfind(tail)
    if at < 0 or not data.endswith(b'"}') or len(data) - at != len(tail) + 128 + 2:
        return False
    body, signature = data[:at] + b"}", bytes.fromhex(data[at + len(tail) : -2].decode())
    try:
        Ed25519PublicKey.from_public_bytes(bytes.fromhex(public)).verify(
            signature, f"hcr-fleet-robot-1\n{key}\n{nonce}\n".encode() + body
        )
    except (InvalidSignature, ValueError):
        return False
    return True


def robots(s: Any) -> list[str]:
    return sorted(str(r.ok.key_expr).split("/")[1] for r in s.liveliness().get("hcr/*/alive", timeout=WAIT_S))


def operators(s: Any, robot: str) -> list[tuple[str, str]]:
    """Every operator session's token on ``robot``, as (OP, SESSION): what anyone on the fleet can list."""
    found = []
    for reply in s.liveliness().get(f"hcr/{robot}/op/*/*", timeout=WAIT_S):
        parts = str(reply.ok.key_expr).split("/")
        found.append((parts[3], parts[4]))
    return found


def drive(s: Any, robot: str) -> None:
    say(robots=robots(s))
    me = Client(s, robot, "rawclient")
    words: list[bytes] = []  # step 7: the robot's word on status, declared before anything is asked of it
    status = s.declare_subscriber(
        f"hcr/{robot}/status", lambda sample: words.append(sample.payload.to_bytes())
    )
    me.declare()
    info = me.info()
    say(deadman=info["deadman"], challenge=len(me.challenge))
    for reply in s.get(f"hcr/{robot}/read/compass", timeout=WAIT_S):
        say(read=json.loads(reply.ok.payload.to_bytes())["reading"])
    ok, answer, _, _ = me.claim()
    say(claimed=ok, answer=answer)
    hold = s.declare_subscriber(f"hcr/{robot}/hold/{answer['hold']}", lambda sample: None)
    me.put(f"hcr/{robot}/cmd_vel", {"address": 1, "command": 1, "content": "B3 B3"}, "cmd_vel")
    for _ in range(5):  # step 6: renew by claiming again, signed, never by repeating the motion
        time.sleep(RENEW_S)
        ok, answer, _, _ = me.claim()
    say(renewed=ok, seen=answer.get("seen"))
    renewing = threading.Event()
    renewer = threading.Thread(target=renew, args=(me, renewing))  # every RENEW_S while the motion runs
    renewer.start()
    sys.stdin.readline()  # the test has seen the motion on the wire
    renewing.set()
    renewer.join()
    nonce = secrets.token_hex(16)
    me.put(f"hcr/{robot}/stop", {"key": me.key, "nonce": nonce}, "stop")
    stopped = made(words, info["key"], robot, nonce)
    ok, answer, _, _ = me.ask(
        f"hcr/{robot}/drive", {"op": me.name, "session": me.session, "do": "release"}, "release"
    )
    say(stopped=stopped, released=ok, driver=answer.get("driver"))
    status.undeclare()
    hold.undeclare()
    me.token.undeclare()


def made(words: list[bytes], robot_key: str, robot: str, nonce: str) -> bool:
    """Step 8: whether the stop asked with ``nonce`` was made: a ``stopped`` word on status, signed by the
    robot's key, naming the nonce in its ``asks`` (waited for ``WAIT_S``)."""
    key, deadline = f"hcr/{robot}/status", time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        for data in list(words):
            word = json.loads(data)
            if word.get("event") == "stopped" and nonce in (word.get("asks") or []):
                return proven(robot_key, key, "-", data)
        time.sleep(0.02)
    return False


def renew(me: Client, done: threading.Event) -> None:
    """Step 6: a signed claim every ``RENEW_S`` until ``done``."""
    while not done.wait(RENEW_S):
        me.claim()


def stranger(s: Any, robot: str) -> None:
    """A claim and motion under a session listed on the fleet, signed with a key of the stranger's own."""
    deadline = time.monotonic() + WAIT_S
    while not (listed := operators(s, robot)) and time.monotonic() < deadline:
        time.sleep(0.05)
    name, session = listed[0]
    me = Client(s, robot, name)
    me.info()
    me.session = session  # the victim's: anyone can list it
    ok, answer, _, _ = me.claim()
    unsigned = me.send(
        f"hcr/{robot}/drive",
        json.dumps({"op": name, "session": session, "do": "claim"}).encode(),
        f"{name} {session} 1".encode(),
    )
    for _ in range(20):
        me.put(f"hcr/{robot}/cmd_vel", {"address": 1, "command": 1, "content": "E6 E6"}, "cmd_vel")
    servo = {"op": name, "session": session, "key": me.key, "address": 1, "command": 0x41, "content": "11 22"}
    wrote, why, _, _ = me.ask(f"hcr/{robot}/write", servo, "write")
    say(
        victim=name,
        claimed=ok,
        answer=answer,
        unsigned_claimed=unsigned[0],
        unsigned=unsigned[1],
        wrote=wrote,
        why=why,
    )


def capture(s: Any, robot: str, path: str) -> None:
    """What anyone on the fleet sees of a drive (a queryable that never replies gets the claim, a
    subscriber the motion): saved, then this session goes."""
    me = Client(s, robot, "captured")
    me.declare()
    me.info()
    ok, answer, payload, attachment = me.claim()
    motion = json.dumps({"address": 1, "command": 1, "content": "B3 B3"}).encode()
    moved = me.attachment("cmd_vel", motion)
    s.put(f"hcr/{robot}/cmd_vel", motion, attachment=moved)
    seq, deadline = me.seq, time.monotonic() + WAIT_S
    confirm = {"op": me.name, "session": me.session, "do": "claim", "confirm": seq}
    while (
        me.ask(f"hcr/{robot}/drive", confirm, "claim")[1].get("seen", 0) < seq and time.monotonic() < deadline
    ):
        time.sleep(0.02)  # step 6: the motion confirmed taken
    with open(path, "w") as out:
        json.dump(
            {
                "session": me.session,
                "payload": payload.hex(),
                "attachment": attachment.hex(),
                "motion": motion.hex(),
                "moved": moved.hex(),
            },
            out,
        )
    say(claimed=ok, answer=answer, seq=seq)


def churn(s: Any, robot: str, count: str) -> None:
    """``count`` throw-away sessions, each with a key the robot side learns (a claim), gone one by one:
    each waited for until the robot side no longer admits it (its token's going taken)."""
    for n in range(int(count)):
        me = Client(s, robot, f"churn{n}")
        me.declare()
        me.info()
        me.claim()
        me.ask(f"hcr/{robot}/drive", {"op": me.name, "session": me.session, "do": "release"}, "release")
        me.token.undeclare()
        asked = json.dumps({"op": me.name, "session": me.session, "do": "lease"}).encode()
        deadline = time.monotonic() + WAIT_S
        # Asked once a turn (``admit`` would ask again while the answer is "token": false, which is gone)
        while me.send(f"hcr/{robot}/drive", asked, None)[0] and time.monotonic() < deadline:
            time.sleep(0.05)
    say(churned=int(count))


def replay(s: Any, robot: str, path: str) -> None:
    """The captured claim and motion sent again under a copy of the session's token; what the robot
    side answered the claim and said on ``status`` of the motion."""
    with open(path) as saved:
        was = json.load(saved)
    heard: list[dict[str, Any]] = []
    status = s.declare_subscriber(
        f"hcr/{robot}/status", lambda sample: heard.append(json.loads(sample.payload.to_bytes()))
    )
    token = s.liveliness().declare_token(f"hcr/{robot}/op/captured/{was['session']}")  # a copy of its token
    deadline = time.monotonic() + WAIT_S
    while True:
        ok, answer = Client(s, robot, "x").send(
            f"hcr/{robot}/drive", bytes.fromhex(was["payload"]), bytes.fromhex(was["attachment"])
        )
        if ok or answer.get("token") is not False or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    seq = int(bytes.fromhex(was["moved"]).split()[2])
    said = None
    while said is None and time.monotonic() < deadline:
        s.put(f"hcr/{robot}/cmd_vel", bytes.fromhex(was["motion"]), attachment=bytes.fromhex(was["moved"]))
        time.sleep(0.1)
        said = next((h for h in list(heard) if h.get("op") == "captured" and h.get("seq") == seq), None)
    say(claimed=ok, answer=answer, motion=said)
    status.undeclare()
    token.undeclare()


def copy(s: Any, robot: str, *subscribed: str) -> None:
    deadline = time.monotonic() + WAIT_S
    while not (listed := operators(s, robot)) and time.monotonic() < deadline:
        time.sleep(0.05)
    tokens = [s.liveliness().declare_token(f"hcr/{robot}/op/{name}/{sid}") for name, sid in listed]
    subscribers = [s.declare_subscriber(key, lambda sample: None) for key in subscribed]
    say(copied=len(tokens), subscribed=len(subscribers))
    time.sleep(3600)


def main() -> None:
    endpoint, robot, what, *rest = sys.argv[1:]
    s = open_session(endpoint)
    try:
        {
            "drive": drive,
            "stranger": stranger,
            "capture": capture,
            "churn": churn,
            "replay": replay,
            "copy": copy,
        }[what](s, robot, *rest)
    finally:
        s.close()


if __name__ == "__main__":
    main()
