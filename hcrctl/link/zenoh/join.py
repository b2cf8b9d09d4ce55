"""Opening a Zenoh session the way every fleet command must: explicit endpoints, no scouting, short lease.

Zenoh's defaults suit a LAN of trusted peers: a peer listens on every
interface, finds others by multicast and, told by a router where other
peers listen (gossip), connects to them directly. A robot console must not:
the router is the only session that listens (``tcp/127.0.0.1:7447`` unless
told), and everything else is a *client* of it (``member``): a client
listens nowhere and connects only to the endpoints it is given, and the
router routes everything between clients. So a fleet reaches across hosts
through its router alone, and a locator learnt from afar (another host's
``127.0.0.1``) is never dialled on this one, where it would join whatever
else listens on this machine's loopback to the fleet. A ``fleet serve`` told
``--listen`` is a peer listening there (a robot reachable directly), still
with multicast scouting and gossip off: it connects only where it is told.

The link lease is 3 s (Zenoh's is 10 s): a peer heard nothing from for that
long is gone, its tokens deleted, so a frozen laptop or a cut cable is
noticed within 3 s (a killed process at once: its TCP closes). The robot
side's deadman (0.5 s unless told) stops the robot before that, as it holds
even when the network does not; the lease stops a silent driver first only
under a deadman over 3 s. Nor may the lease lapse on a peer that is there:
that deletes a live driver's token, which the robot side must take for the
driver gone, and stop. Keep-alives go every quarter lease, so a lease may
lapse on a process stalled for three quarters of it: 0.75 s of a 1 s lease
is a stall a loaded 2-core machine has been seen to reach; 3 s allows 2.25 s.

A client whose router goes away connects again by itself and declares again
what it had declared (its tokens, subscribers, queryables), so a router
restarted, or a cable plugged back in, finds its robots and operators as
they were. A
``--zenoh-config`` file (Zenoh's JSON5: TLS, user/password, access control)
is read first; the command line wins over it, and the file wins over the
defaults; the mode, the lease and scouting (off) are always this module's.

Zenoh itself is imported only here, on the first fleet command, and its
absence is one line naming the extra.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

from ...errors import HcrError
from ...extras import require
from ..loopback import is_loopback
from .keyspace import DEFAULT_ENDPOINT

#: Zenoh's transport lease, ms: a peer silent this long is gone (its tokens deleted). Long enough that a
#: loaded machine's stall does not drop a live session, short beside Zenoh's 10 s; the deadman stops first.
LEASE_MS = 3000
#: What a peer listens on when not told: loopback, a free port.
LOOPBACK_ANY = "tcp/127.0.0.1:0"
ROUTER, PEER, CLIENT = "router", "peer", "client"
#: How often a robot served before its router (or while it restarts) asks for it again, s.
RETRY_S = 0.5
#: What no fleet session does, whatever a ``--zenoh-config`` file says: find or dial what was not named.
QUIET = {"scouting/multicast/enabled": False, "scouting/gossip/enabled": False}


JOIN_HINT = (
    "start a router with 'hcrctl fleet router', or say where the fleet is with --zenoh ENDPOINT "
    "(and --zenoh-config for TLS or a password)"
)


class FleetError(HcrError):
    """A fleet session could not open, or a fleet robot could not be reached (exit 1, with a hint)."""


def import_zenoh() -> ModuleType:
    """The ``zenoh`` module; MissingExtra (the zenoh extra named) only when that package itself is absent."""
    return require("zenoh", "zenoh", "the fleet")


@dataclass(frozen=True)
class Where:
    """Where the fleet is, from the global ``--zenoh``/``--zenoh-config`` and a command's own options."""

    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    config_file: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def joined(self, connect: Sequence[str] = (), listen: Sequence[str] = ()) -> Where:
        """These endpoints added to a command's own (``fleet serve --connect/--listen``)."""
        return Where((*self.connect, *connect), (*self.listen, *listen), self.config_file, dict(self.extra))


def endpoint_host(endpoint: str) -> str | None:
    """The host of ``proto/host:port[#opts]``, or None for an endpoint without one (a unix socket)."""
    proto, _, rest = endpoint.partition("/")
    if not rest or proto.startswith("unixsock"):
        return None
    address = rest.split("#", 1)[0].split("?", 1)[0]
    return address.rsplit(":", 1)[0] if ":" in address else address


def beyond_loopback(endpoints: Sequence[str]) -> list[str]:
    """The endpoints that listen past this machine (said as a warning, as ``bridge --listen`` does)."""
    return [e for e in endpoints if (host := endpoint_host(e)) is not None and not is_loopback(host)]


def config(mode: str, where: Where) -> Any:
    """A ``zenoh.Config`` for ``mode`` (``router``, ``peer`` or ``client``) at ``where``."""
    zenoh = import_zenoh()
    cfg = _base(zenoh, where.config_file)
    _set(cfg, "mode", mode)
    for key, value in QUIET.items():
        _set(cfg, key, value)
    _set(cfg, "transport/link/tx/lease", LEASE_MS)
    listen = list(where.listen) or _file_value(cfg, "listen/endpoints", where.config_file) or _listen(mode)
    _set(cfg, "listen/endpoints", [] if mode == CLIENT else listen)
    connect = list(where.connect) or _file_value(cfg, "connect/endpoints", where.config_file)
    _set(cfg, "connect/endpoints", connect or ([] if mode == ROUTER else [DEFAULT_ENDPOINT]))
    for key, value in where.extra.items():
        _set(cfg, key, value)
    return cfg


def member(where: Where) -> str:
    """The mode of a session that is not the router: a client, or a peer where it is told to listen."""
    return PEER if where.listen else CLIENT


def _listen(mode: str) -> list[str]:
    return {ROUTER: [DEFAULT_ENDPOINT], PEER: [LOOPBACK_ANY]}.get(mode, [])


def _base(zenoh: ModuleType, path: str | None) -> Any:
    if path is None:
        return zenoh.Config()
    try:
        return zenoh.Config.from_file(path)
    except Exception as exc:  # zenoh raises its own ZError, or OSError-like text, for a bad file
        raise FleetError(
            f"cannot read the Zenoh configuration {path}: {exc}",
            hint="--zenoh-config takes Zenoh's JSON5 configuration (docs/fleet.md)",
        ) from exc


def _file_value(cfg: Any, key: str, path: str | None) -> list[str]:
    """What the configuration file set for ``key`` (an endpoint list; a per-mode table is left to Zenoh)."""
    if path is None:
        return []
    value = json.loads(cfg.get_json(key))
    return list(value) if isinstance(value, list) else []


def _set(cfg: Any, key: str, value: object) -> None:
    cfg.insert_json5(key, json.dumps(value))


def open_session(mode: str, where: Where) -> Any:
    """``zenoh.open`` with ``config(mode, where)``; a refusal (a bad endpoint, a port in use) is FleetError."""
    zenoh = import_zenoh()
    cfg = config(mode, where)
    try:
        return zenoh.open(cfg)
    except Exception as exc:  # ZError: an endpoint that cannot be bound or parsed, bad TLS files...
        endpoints = ", ".join(where.listen or where.connect) or DEFAULT_ENDPOINT
        raise FleetError(
            f"cannot open a Zenoh session ({mode}) at {endpoints}: {said(exc)}",
            hint="check --zenoh/--listen endpoints (tcp/HOST:PORT) and --zenoh-config",
        ) from exc


def join(where: Where) -> Any:
    """A client session of the fleet at ``where``; FleetError naming where it looked (and what to start)."""
    try:
        return open_session(CLIENT, where)
    except FleetError as exc:
        raise FleetError(f"cannot reach the fleet at {looked_at(where)}", hint=JOIN_HINT) from exc


def looked_at(where: Where) -> str:
    """Where a session at ``where`` looks for the fleet, as said to the user."""
    return ", ".join(where.connect) or DEFAULT_ENDPOINT


def open_member(where: Where, stopped: Callable[[], bool], note: Callable[[str], None]) -> Any | None:
    """The session of a robot's serve (``member``); None if ``stopped()`` before it opened.

    A robot may be served before its router starts: a client asks for the
    router every ``RETRY_S`` until it answers, saying once on ``note`` what it
    waits for and what Zenoh said (a router down, or one refusing this
    session's TLS or password). A peer opens at once and connects when it can.
    """
    mode = member(where)
    if mode != CLIENT:
        return open_session(mode, where)
    told = False
    while not stopped():
        try:
            return open_session(CLIENT, where)
        except FleetError as exc:
            if not told:
                note(f"waiting for the fleet's router at {looked_at(where)} (zenoh: {said(exc.__cause__)})")
                told = True
            time.sleep(RETRY_S)
    return None


def said(exc: BaseException | None) -> str:
    """What Zenoh said, without the place in its Rust source it appends (`` at /root/.cargo/...rs:447.``)."""
    return str(exc).split(" at /", 1)[0].strip()
