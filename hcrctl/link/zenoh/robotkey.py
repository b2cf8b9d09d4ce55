"""A robot's own key: how an operator tells the robot it reached from any peer answering in its name.

Anyone on the fleet may declare ``hcr/R/alive`` and answer ``R``'s queries
(Zenoh says nobody's name), so what a robot answers proves nothing by
itself. Each served robot therefore has an Ed25519 key pair of its own
(``RobotKey``), made by its first ``fleet serve`` and kept on its computer
(``key_path``, mode 0600): the same library and the same kind of key as the
operators' sessions (``identity``), since only a signature that a party
without the secret can check proves anything to it; a secret shared by the
whole fleet would let any member sign as any robot.

An operator asks with a fresh *nonce* (``"nonce"``: 32 hex digits, in the
query's JSON payload, and in a stop's), and the robot side signs its answer
over the key expression it answers on, that nonce, and the answer's bytes
(``answer_bytes``), so no answer is good for another question, another robot
or another key: a recorded answer replayed later is refused. The signature
rides inside the answer's JSON object as its last member (``seal``), because
Zenoh's error replies carry no attachment. The robot's status words are
signed the same way, their nonce ``-``; the word of a stop names the nonces of
the stops it answers (``asks``).

The operator remembers each robot's public key in ``known_path`` the first time
it reaches it (trust on first use, as ssh's ``known_hosts``) and from then on
believes only that key: a robot answering with another is refused, naming both
fingerprints. A line written there by hand, or the config's ``[robot-keys]``
(``robotpins``, which wins over it), pins a robot's key before first use.
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import os
import re
import secrets
import stat
import subprocess
import sys
from collections.abc import Mapping
from typing import Any

from ...errors import NotTheRobot
from .. import robotpins
from .identity import PUBLIC_KEY, _ed25519, check_installed, verified
from .join import FleetError

#: What this scheme is: the first line of what a robot signs, never mistaken for an operator's ``hcr-fleet-2``.
SCHEME = "hcr-fleet-robot-1"
#: A question's nonce: 32 lower-case hex digits (``new_nonce``).
NONCE = re.compile(r"[0-9a-f]{32}")
#: The nonce of what answers no one question (a status word).
UNASKED = "-"
#: The sealed answer's last member: ``, "signature": "<128 hex>"}``.
TAIL = re.compile(rb', "signature": "([0-9a-f]{128})"\}\Z')
TAIL_HEAD = b', "signature": "'
APP_DIR = "hcrctl"


class NotProven(FleetError, NotTheRobot):
    """An answer that its robot's key did not sign for this question (exit 1): a fake, or a changed key."""


def unproven(robot: str, why: str) -> str:
    """How every refusal of an answer begins: ``R could not prove it is R: <why>``."""
    return f"{robot} could not prove it is {robot}: {why}"


def data_dir(environ: Mapping[str, str] = os.environ) -> str:
    """``$XDG_DATA_HOME/hcrctl`` when that is absolute, else ``~/.local/share/hcrctl``."""
    base = environ.get("XDG_DATA_HOME", "")
    root = base if os.path.isabs(base) else os.path.join(os.path.expanduser("~"), ".local", "share")
    return os.path.join(root, APP_DIR)


def key_path(robot: str) -> str:
    """Where ``fleet serve ROBOT`` keeps its robot's private key."""
    return os.path.join(data_dir(), "fleet", "keys", f"{robot}.key")


def known_path() -> str:
    """The operator's known robots: one ``NAME PUBLIC_KEY`` a line."""
    return os.path.join(data_dir(), "fleet", "known_robots")


def fingerprint(public_hex: str) -> str:
    """A public key as people compare it, as ssh does: ``SHA256:`` and its digest in base64."""
    digest = hashlib.sha256(bytes.fromhex(public_hex)).digest()
    return robotpins.PREFIX + base64.b64encode(digest).decode().rstrip("=")


def new_nonce() -> str:
    return secrets.token_hex(16)


def ask_of(message: object) -> str:
    """The nonce a question's JSON object carries, ``UNASKED`` when it carries none that is one."""
    nonce = message.get("nonce") if isinstance(message, dict) else None
    return nonce if isinstance(nonce, str) and NONCE.fullmatch(nonce) else UNASKED


def answer_bytes(key_expr: str, ask: str, body: bytes) -> bytes:
    """What a robot signs: ``SCHEME``, the key expression answered on, the question's nonce, the body."""
    return f"{SCHEME}\n{key_expr}\n{ask}\n".encode("ascii") + body


def seal(body: bytes, signature: str) -> bytes:
    """``body`` (a JSON object with at least one member) with ``"signature"`` as its last member."""
    assert body.endswith(b"}") and body != b"{}", body[:40]
    return body[:-1] + TAIL_HEAD + signature.encode("ascii") + b'"}'


def unseal(data: bytes) -> tuple[bytes, str] | None:
    """(the body as signed, the signature) of a sealed answer; None when it carries no signature."""
    found = TAIL.search(data)
    if found is None:
        return None
    return data[: found.start()] + b"}", found.group(1).decode("ascii")


class RobotKey:
    """A served robot's key pair, read from ``key_path`` or made there on first serve.

    The file holds the private key's 32 bytes and then the public key's, each as 64 hex digits on a
    line: the fingerprint is known at start without loading ``cryptography`` (7 MB of a serve's memory),
    which is loaded on the first answer signed.
    """

    def __init__(self, private_hex: str, public_hex: str) -> None:
        self._private_hex = private_hex
        self._private: Any = None
        self.public_hex = public_hex
        self.fingerprint = fingerprint(public_hex)

    @classmethod
    def load(cls, robot: str) -> RobotKey:
        """The robot's key; made (mode 0600) when there is none. FleetError when it cannot be read or made,
        or others may read it."""
        path = key_path(robot)
        try:
            lines = _read_private(path).split()
        except FileNotFoundError:
            made = cls(*_made_apart())
            _write_private(path, f"{made._private_hex}\n{made.public_hex}")
            return made
        except OSError as exc:
            raise FleetError(f"cannot read {robot}'s key at {path}: {exc.strerror}") from None
        if len(lines) != 2 or not all(PUBLIC_KEY.fullmatch(line) for line in lines):
            raise FleetError(
                f"{path} is not a robot key (two lines of 64 hex digits)",
                hint=f"move it away: the next fleet serve {robot} makes a new key (operators see it changed)",
            )
        return cls(*lines)

    def sealed(self, key_expr: str, ask: str, body: bytes) -> bytes:
        """``body`` signed for the question ``ask`` answered on ``key_expr`` (``seal``)."""
        if self._private is None:
            private = _ed25519().Ed25519PrivateKey.from_private_bytes(bytes.fromhex(self._private_hex))
            if private.public_key().public_bytes_raw().hex() != self.public_hex:
                raise FleetError("the robot key's two halves do not match: it signs nothing")
            self._private = private
        return seal(body, self._private.sign(answer_bytes(key_expr, ask, body)).hex())


#: Makes a key pair and prints its two halves, in a process of its own (``_made_apart``).
MAKE_KEY = (
    "from cryptography.hazmat.primitives.asymmetric import ed25519\n"
    "k = ed25519.Ed25519PrivateKey.generate()\n"
    "print(k.private_bytes_raw().hex(), k.public_key().public_bytes_raw().hex())\n"
)


def _made_apart() -> tuple[str, str]:
    """A new key pair's (private, public) hex, made by a short-lived Python process: a first serve does not
    carry the signatures' library (7 MB) before anyone asks it anything."""
    check_installed()  # MissingExtra, naming the zenoh extra, when cryptography is absent (not imported)
    done = subprocess.run([sys.executable, "-c", MAKE_KEY], capture_output=True, text=True, check=False)
    halves = done.stdout.split()
    if done.returncode != 0 or len(halves) != 2 or not all(PUBLIC_KEY.fullmatch(h) for h in halves):
        raise FleetError(f"could not make the robot's key: {done.stderr.strip()[-200:] or 'no output'}")
    return halves[0], halves[1]


def _read_private(path: str) -> str:
    info = os.stat(path)
    if info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise FleetError(
            f"{path} may be read by others (mode {stat.S_IMODE(info.st_mode):o}): the robot's key is refused",
            hint=f"chmod 600 {path}",
        )
    with open(path, encoding="ascii") as file:
        return file.read(300)


def _write_private(path: str, text: str) -> None:
    try:
        os.makedirs(os.path.dirname(path), mode=0o700, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError as exc:
        raise FleetError(f"cannot make the robot's key at {path}: {exc.strerror}") from None
    with os.fdopen(fd, "w", encoding="ascii") as file:
        file.write(text + "\n")


class RobotProof:
    """The operator's check of one robot's answers: its public key, as remembered (``KnownRobots``)."""

    def __init__(self, robot: str, public_hex: str) -> None:
        self.robot = robot
        self.public_hex = public_hex
        self.fingerprint = fingerprint(public_hex)
        self._key = _ed25519().Ed25519PublicKey.from_public_bytes(bytes.fromhex(public_hex))

    def body(self, key_expr: str, ask: str, data: bytes) -> bytes | None:
        """The answer's body if this robot signed it for ``ask`` on ``key_expr``; None otherwise."""
        sealed = unseal(data)
        if sealed is None:
            return None
        body, signature = sealed
        return body if verified(self._key, answer_bytes(key_expr, ask, body), signature) else None


def proof_of(robot: str, key_expr: str, ask: str, data: bytes, named: object) -> RobotProof:
    """The proof of a robot's ``info`` answer (``named``: the key it names), checked against itself: the
    answer must be that key's over this question. NotProven otherwise; the known key is ``KnownRobots``'."""
    if not isinstance(named, str) or not PUBLIC_KEY.fullmatch(named):
        raise NotProven(unproven(robot, "its info names no robot key"), hint=HINT)
    proof = RobotProof(robot, named)
    if proof.body(key_expr, ask, data) is None:
        raise NotProven(
            unproven(
                robot, f"its info is not signed by the key it names ({proof.fingerprint}) for this question"
            ),
            hint=HINT,
        )
    return proof


HINT = (
    "a peer answering in its name (a fake robot), or an older fleet serve; hcrctl fleet list shows the keys"
)


class KnownRobots:
    """The robots this operator has reached, by name, and their public keys (``known_path``)."""

    def __init__(self, path: str | None = None) -> None:
        self.path = path or known_path()

    def read(self) -> dict[str, str]:
        found: dict[str, str] = {}
        with (
            contextlib.suppress(FileNotFoundError),
            open(self.path, encoding="ascii", errors="replace") as file,
        ):
            for line in file:
                fields = line.split()
                if len(fields) == 2 and not fields[0].startswith("#") and PUBLIC_KEY.fullmatch(fields[1]):
                    found.setdefault(fields[0], fields[1])
        return found

    def changed(self, proof: RobotProof) -> str | None:
        """Why ``proof``'s key is refused (another is pinned for its robot in the config, else known), or None."""
        pin = robotpins.pinned(proof.robot)
        if pin is not None:
            if pin.fingerprint == proof.fingerprint:
                return None
            return (
                f"{proof.robot}'s key is not the pinned one: it answers with {proof.fingerprint}, "
                f"but {pin.fingerprint} is pinned for it in {pin.where(proof.robot)}"
            )
        known = self.read().get(proof.robot)
        if known is None or known == proof.public_hex:
            return None
        return (
            f"{proof.robot}'s key has changed: it answers with {proof.fingerprint}, "
            f"but {fingerprint(known)} is known for it in {self.path}"
        )

    def check(self, proof: RobotProof) -> None:
        """Believe ``proof`` if its key is the one pinned or known for its robot; remember it when none is
        (first use). NotProven, naming both fingerprints, when another is."""
        why = self.changed(proof)
        pin = robotpins.pinned(proof.robot)
        if why is not None:
            anew = (
                f"change {robotpins.TABLE}.{proof.robot} in {pin.path}"
                if pin is not None
                else f"remove its line from {self.path}"
            )
            raise NotProven(
                why, hint=f"if {proof.robot}'s key was made anew, {anew}; else a peer answers in its name"
            )
        if pin is None and proof.robot not in self.read():
            self._remember(proof)

    def _remember(self, proof: RobotProof) -> None:
        with contextlib.suppress(OSError):  # a read-only home: believed for this run, asked again next time
            os.makedirs(os.path.dirname(self.path), mode=0o700, exist_ok=True)
            fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o600)
            with os.fdopen(fd, "a", encoding="ascii") as file:
                file.write(f"{proof.robot} {proof.public_hex}\n")
