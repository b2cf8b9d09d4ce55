"""Opening a Zenoh session the way every fleet command must: explicit endpoints, no scouting, short lease.

Zenoh's defaults suit a LAN of trusted peers: a peer listens on every
interface and finds others by multicast. A robot console must not: every
session here sets its listen endpoints (loopback unless told), multicast
scouting is off, and everyone connects to the router at ``DEFAULT_ENDPOINT``
unless ``--zenoh`` says where the fleet is. The link lease is 1 s (Zenoh's is
10 s), so a frozen laptop or a cut cable is noticed in under a second; the
robot's own deadman still stops it sooner, as it holds even when the network
does not. A ``--zenoh-config`` file (Zenoh's JSON5: TLS, user/password,
access control) is read first; the command line wins over it, and the file
wins over the defaults.

Zenoh itself is imported only here, on the first fleet command, and its
absence is one line naming the extra.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

from ..errors import HcrError
from ..extras import require
from ..link.loopback import is_loopback
from .keys import DEFAULT_ENDPOINT

#: Zenoh's transport lease, ms: a peer silent this long is gone (its tokens deleted).
LEASE_MS = 1000
#: What a peer listens on when not told: loopback, a free port.
LOOPBACK_ANY = "tcp/127.0.0.1:0"


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
    _set(cfg, "scouting/multicast/enabled", False)
    _set(cfg, "transport/link/tx/lease", LEASE_MS)
    listen = list(where.listen) or _file_value(cfg, "listen/endpoints", where.config_file) or _listen(mode)
    _set(cfg, "listen/endpoints", listen)
    connect = list(where.connect) or _file_value(cfg, "connect/endpoints", where.config_file)
    _set(cfg, "connect/endpoints", connect or ([] if mode == "router" else [DEFAULT_ENDPOINT]))
    for key, value in where.extra.items():
        _set(cfg, key, value)
    return cfg


def _listen(mode: str) -> list[str]:
    return {"router": [DEFAULT_ENDPOINT], "peer": [LOOPBACK_ANY]}.get(mode, [])


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
            f"cannot open a Zenoh session ({mode}) at {endpoints}: {exc}",
            hint="check --zenoh/--listen endpoints (tcp/HOST:PORT) and --zenoh-config",
        ) from exc
