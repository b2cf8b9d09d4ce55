"""Serve the simulator on a pseudo-terminal or a TCP port, until SIGINT/SIGTERM.

A real program (minicom, another tool, ``hcrctl --port /dev/pts/N``) then
talks to the simulated robot through a real file descriptor. Both servers are
one single-threaded select() loop that sleeps until input arrives, the stop
pipe is written, or a link's ``next_due()`` (a paced byte, a broadcast). The
TCP server takes several clients at once, all on the same robot (``sim.hub``).

Output is written non-blocking and dropped when nobody reads, as a UART's
bytes are lost with no listener; the server never stalls on a slow client.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import tty
from collections.abc import Callable

from ..signals import STOP_SIGNALS, SignalFlag
from .hub import Hub, Tap
from .options import SimOptions
from .uart import SimLine, open_link


class Stopper(SignalFlag):
    """A stop flag (``SignalFlag``) plus a readable fd, so a select() loop ends cleanly on a signal.

    The stop signals only set the flag and write the pipe: no exception flies
    through the loop, so fds are closed and the exit status is 0.
    """

    def __init__(self, handle_signals: bool = True) -> None:
        super().__init__()
        self._signals = STOP_SIGNALS if handle_signals else ()
        self._handling = contextlib.ExitStack()
        self._r, self._w = os.pipe()
        os.set_blocking(self._r, False)
        os.set_blocking(self._w, False)

    def __enter__(self) -> Stopper:
        self._handling.enter_context(self.catching(self._signals))
        return self

    def __exit__(self, *exc: object) -> None:
        self._handling.close()
        os.close(self._r)
        os.close(self._w)

    def __call__(self, signum: int, frame: object) -> None:
        super().__call__(signum, frame)
        self._wake()

    @property
    def stopped(self) -> bool:
        return self.is_set()

    def stop(self) -> None:
        """Ask the loop to end; safe from a signal handler or another thread."""
        self.event.set()
        self._wake()

    def _wake(self) -> None:
        with contextlib.suppress(OSError):  # a full pipe means a wake-up is already pending
            os.write(self._w, b"\0")

    def fileno(self) -> int:
        return self._r


def _wait(fd: int, stopper: Stopper, timeout: float | None = None) -> bool:
    """Sleep until ``fd`` is readable (True), or the stop pipe or the timeout (False)."""
    waitables: list[int | Stopper] = [fd, stopper]
    readable, _, _ = select.select(waitables, [], [], timeout)
    return fd in readable


def _timeout(link: SimLine) -> float | None:
    """Seconds until the link's next event (a paced byte, a broadcast); None is never."""
    due = link.next_due()
    return None if due is None else max(0.0, due - link.clock())


def _serve(
    link: SimLine,
    fd: int,
    recv: Callable[[], bytes | None],
    send: Callable[[bytes], object],
    stopper: Stopper,
) -> None:
    """Shuttle bytes between ``fd`` and the link until stopped or the peer hangs up."""
    while not stopper.stopped:
        if _wait(fd, stopper, _timeout(link)):
            data = recv()
            if data == b"":
                return
            if data:
                link.write(data)
        out = link.read()
        if out:
            with contextlib.suppress(BlockingIOError, BrokenPipeError, ConnectionResetError):
                send(out)  # nobody reading: the bytes are lost, as on a real line


def serve_pty(options: SimOptions, stopper: Stopper, on_ready: Callable[[str], None]) -> None:
    """Serve on a new pseudo-terminal; ``on_ready`` gets the device path.

    The slave end stays open here, so clients can open and close the device
    as often as they like without the master seeing a hang-up.
    """
    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        os.set_blocking(master, False)
        link = open_link(options)
        on_ready(os.ttyname(slave))
        _serve(link, master, lambda: _read_pty(master), lambda data: os.write(master, data), stopper)
    finally:
        os.close(master)
        os.close(slave)


def _read_pty(fd: int) -> bytes | None:
    """What the client wrote; None when nothing is there (a pty master never reports EOF here)."""
    try:
        return os.read(fd, 4096) or None
    except (BlockingIOError, InterruptedError):
        return None


#: Clients served at once; one more is told so (on stderr here) and closed.
MAX_CLIENTS = 16


def serve_tcp(
    options: SimOptions,
    host: str,
    port: int,
    stopper: Stopper,
    on_ready: Callable[[str], None],
    say: Callable[[str], None] = lambda _line: None,
) -> None:
    """Serve on TCP, several clients at once sharing one robot; ``on_ready`` gets the ``socket://`` URL.

    The robot outlives its clients (unplugging a cable does not reset it);
    each client starts with a clean line, hears the replies to its own
    requests and every broadcast (see ``sim.hub``). ``say`` gets a line when a
    client comes or goes. Port 0 picks a free port.
    """
    with socket.create_server((host, port)) as server, contextlib.ExitStack() as conns:
        server.setblocking(False)
        hub = Hub(options)
        clients: dict[socket.socket, tuple[SimLine[Tap], str]] = {}
        on_ready(socket_url(host, server.getsockname()[1]))
        while not stopper.stopped:
            timeouts = [t for link, _ in clients.values() if (t := _timeout(link)) is not None]
            waitables: list[socket.socket | Stopper] = [server, stopper, *clients]
            readable, _, _ = select.select(waitables, [], [], min(timeouts, default=None))
            if server in readable:
                _accept(server, hub, clients, conns, say)
            for conn in [c for c in readable if c in clients]:
                _take_input(conn, hub, clients, say)
            for conn, (link, _) in list(clients.items()):
                out = link.read()
                if out:
                    with contextlib.suppress(BlockingIOError, BrokenPipeError, ConnectionResetError):
                        conn.send(out)  # nobody reading: the bytes are lost, as on a real line


def _accept(
    server: socket.socket,
    hub: Hub,
    clients: dict[socket.socket, tuple[SimLine[Tap], str]],
    conns: contextlib.ExitStack,
    say: Callable[[str], None],
) -> None:
    try:
        conn, peer = server.accept()
    except (BlockingIOError, InterruptedError, ConnectionAbortedError):
        return
    who = _peer_name(peer)
    if len(clients) >= MAX_CLIENTS:
        conn.close()
        say(f"refused {who}: {MAX_CLIENTS} clients are connected already (the most served at once)")
        return
    conns.enter_context(conn)
    conn.setblocking(False)
    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    clients[conn] = (hub.attach(), who)
    say(f"{who} connected ({_count(len(clients))})")


def _take_input(
    conn: socket.socket,
    hub: Hub,
    clients: dict[socket.socket, tuple[SimLine[Tap], str]],
    say: Callable[[str], None],
) -> None:
    link, who = clients[conn]
    data = _recv(conn)
    if data == b"":
        hub.detach(link)
        del clients[conn]
        conn.close()
        say(f"{who} disconnected ({_count(len(clients))})")
    elif data:
        link.write(data)


def _count(n: int) -> str:
    return f"{n} client{'s' if n != 1 else ''} connected"


def _peer_name(peer: object) -> str:
    if isinstance(peer, tuple) and len(peer) >= 2:
        return f"[{peer[0]}]:{peer[1]}" if ":" in str(peer[0]) else f"{peer[0]}:{peer[1]}"
    return str(peer)


def _recv(conn: socket.socket) -> bytes | None:
    try:
        return conn.recv(4096)
    except (BlockingIOError, InterruptedError):
        return None
    except OSError:
        return b""  # reset by the peer: treat as a hang-up


def socket_url(host: str, port: int) -> str:
    """The pyserial URL of a TCP server; IPv6 literals need brackets."""
    return f"socket://[{host}]:{port}" if ":" in host else f"socket://{host}:{port}"
