"""``hcrctl fleet router``: Zenoh's own router mode, in this process, until Ctrl-C, SIGTERM or SIGHUP.

``zenohd`` is not on PyPI; ``zenoh.open`` in mode ``router`` is a router.
It listens where it is told (``--listen``, else the global ``--zenoh``
endpoints, which is where everyone else will connect, else a
``--zenoh-config`` file's, else ``tcp/127.0.0.1:7447``). Its first line of
stdout is where (the endpoints, space-separated, flushed, so a script can
wait for it and connect there); stderr says it as a sentence. It connects
to nobody unless a ``--zenoh-config`` says so.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence

from ..errors.terminal import warn
from ..link.zenoh.join import Where, beyond_loopback, config, open_session
from ..link.zenoh.keyspace import DEFAULT_ENDPOINT
from ..signals import TERMINATING, SignalFlag


def where(listen: Sequence[str], zenoh: Sequence[str], config_file: str | None) -> Where:
    """``--listen``, else the ``--zenoh`` endpoints, else (in ``session``) the file's, else the default."""
    return Where((), tuple(listen) or tuple(zenoh), config_file)


def listening(at: Where) -> list[str]:
    """Where a router at ``at`` listens, as its configuration says once every source is applied."""
    found = json.loads(config("router", at).get_json("listen/endpoints"))
    return [str(e) for e in found] if isinstance(found, list) else [DEFAULT_ENDPOINT]


def run_router(at: Where, on_ready: Callable[[str], None]) -> None:
    """Route until a stop signal (or Ctrl-C), then close and return; ``on_ready`` gets where, once listening."""
    endpoints = listening(at)
    for endpoint in beyond_loopback(endpoints):
        warn(f"listening on {endpoint}: anyone on the network who can reach it joins the fleet")
    done = SignalFlag()
    with done.catching(TERMINATING):
        session = open_session("router", at)
        try:
            on_ready(" ".join(endpoints))
            try:
                while not done.event.wait(0.5):
                    pass
            except KeyboardInterrupt:
                pass
        finally:
            session.close()
