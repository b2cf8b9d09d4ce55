"""An operator session's identity on the fleet: an Ed25519 key pair, and what each signature covers.

A session id that anyone can list (every operator's liveliness token names
it) proves nothing. So each operator session draws a key pair when it opens
a robot; its session id is derived from the public key (``session_of``: the
first 16 hex digits of its SHA-256), and every message it sends that could
move the robot or take its lease is signed with the private key, which never
leaves the process. The robot side learns the public key from the session's
first claim (or write), checks that it is the one the session id was derived
from, and from then on takes only what that key signed.

What is signed (``signed_bytes``) is a head of text lines, then the
message's payload exactly as sent::

    hcr-fleet-2\\n CHALLENGE\\n LEASE\\n ROBOT\\n WHAT\\n OP\\n SESSION\\n SEQ\\n PAYLOAD

``CHALLENGE`` is the 32 hex digits the serving process drew when it
started (in its ``info``), so nothing signed for one ``fleet serve`` is good
for another; ``LEASE`` the 32 hex digits it drew when it admitted the
session (its token came; a ``drive`` query ``{"do": "lease"}`` answers it),
so nothing signed in one admission is good in another, whatever the serve
still remembers of sessions gone; ``WHAT`` the kind of message (``WHATS``), so a signed claim is
never good as a motion; ``SEQ`` the decimal sequence number, counting up
from 1 over all of the session's messages. The signature travels in the
message's attachment, ``OP SESSION SEQ SIGNATURE`` (``keyspace.attachment``),
as 128 lower-case hex digits.

``cryptography`` (pyca) is in the zenoh extra and imported on first use
only, so nothing outside the fleet loads it.
"""

from __future__ import annotations

import hashlib
import importlib.util
import re
from typing import Any

from .keyspace import Who

#: The kinds of signed message: the drive lease's two, motion, a non-motion write, and a stop.
WHATS = ("claim", "release", "cmd_vel", "write", "stop")
#: The signed bytes' first line: what this scheme is, so a later one is never mistaken for it.
SCHEME = "hcr-fleet-2"
#: A public key: 64 lower-case hex digits, its 32 raw bytes.
PUBLIC_KEY = re.compile(r"[0-9a-f]{64}")


def _ed25519() -> Any:
    from ...extras import require

    require("cryptography", "zenoh", "the fleet")
    from cryptography.hazmat.primitives.asymmetric import ed25519

    return ed25519


def check_installed() -> None:
    """MissingExtra (the zenoh extra named) now if cryptography is absent, without importing it: a serve
    that loaded it at start would carry its 7 MB before anyone claims."""
    if importlib.util.find_spec("cryptography") is None:
        _ed25519()


def session_of(public: bytes) -> str:
    """The session id a public key (its 32 raw bytes) stands for: its SHA-256's first 16 hex digits."""
    return hashlib.sha256(public).hexdigest()[:16]


def signed_bytes(
    challenge: str, lease: str, robot: str, what: str, op: Who, seq: int, payload: bytes
) -> bytes:
    """Exactly what a signature covers (see the module's docstring)."""
    head = f"{SCHEME}\n{challenge}\n{lease}\n{robot}\n{what}\n{op.name}\n{op.session}\n{seq}\n"
    return head.encode("ascii") + payload


class Identity:
    """This operator session's key pair; its session id is the public key's (``session_of``)."""

    def __init__(self) -> None:
        self._private = _ed25519().Ed25519PrivateKey.generate()
        self.public = self._private.public_key().public_bytes_raw()
        self.session = session_of(self.public)

    @property
    def public_hex(self) -> str:
        return self.public.hex()

    def sign(self, data: bytes) -> str:
        return self._private.sign(data).hex()


def public_key(text: object, session: str) -> Any | None:
    """The verifying key ``text`` (64 hex digits) spells, if it is the one ``session`` was derived from."""
    if not isinstance(text, str) or not PUBLIC_KEY.fullmatch(text):
        return None
    raw = bytes.fromhex(text)
    if session_of(raw) != session:
        return None
    try:
        return _ed25519().Ed25519PublicKey.from_public_bytes(raw)
    except ValueError:
        return None


def raw(key: Any) -> bytes:
    """A verifying key's 32 raw bytes: how a session gone is remembered (a verifier object costs far more)."""
    data: bytes = key.public_bytes_raw()
    return data


def verifier(data: bytes) -> Any:
    """The verifying key of 32 raw bytes (``raw``'s)."""
    return _ed25519().Ed25519PublicKey.from_public_bytes(data)


def verified(key: Any | None, data: bytes, signature: str) -> bool:
    """Whether ``signature`` (128 hex digits) is ``key``'s over ``data``."""
    if key is None or len(signature) != 128:
        return False
    try:
        key.verify(bytes.fromhex(signature), data)
    except Exception:  # InvalidSignature, or hex that is not: either way not signed
        return False
    return True
