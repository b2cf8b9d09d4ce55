"""``sim://[?options]``: the simulated robot as a pyserial port, in process, in real time.

The options are the ``SimOptions`` query keys (``sim://?drop=0.1&seed=3``).
Nothing touches the OS: the simulator runs on ``time.monotonic`` inside the
caller's process. One thread may block in ``read()`` while another writes;
a ``threading.Condition`` wakes the reader as soon as reply bytes exist, and
otherwise it sleeps exactly until ``next_due()`` (a broadcast, a delayed
reply, a paced byte), never polling on a fixed tick.

The port's ``baudrate`` setting is accepted and ignored, as with ``loop://``:
line pacing is chosen in the URL (``pace=1&baud=9600``) so that a client's
default baud rate cannot silently slow a test down.
"""

from __future__ import annotations

import threading
import time
import urllib.parse
from typing import TYPE_CHECKING, Any

# types-pyserial leaves out serialutil.to_bytes, which pyserial 3.5 has and its own handlers use.
from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes  # type: ignore[attr-defined]

from ..sim.options import SimOptions
from ..sim.simulator import Simulator
from ..sim.uart import SimLine, open_link
from .cable import HealthyCable

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer

#: The shortest wait, so a due time that has just passed cannot spin the reader.
_MIN_WAIT_S = 1e-4


class Serial(HealthyCable, SerialBase):
    """A serial port whose other end is the simulated robot."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._cond = threading.Condition()
        self._link: SimLine[Simulator] | None = None
        self._rx = bytearray()
        self._cancelled = False
        self.options = SimOptions()
        super().__init__(*args, **kwargs)

    @property
    def simulator(self) -> Simulator:
        """The model behind the port, for tests and demos that need to look inside."""
        if self._link is None:
            raise PortNotOpenError()
        return self._link.sim

    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        port = self.port
        if port is None:
            raise SerialException("Port must be configured before it can be used.")
        self.options = self.from_url(port)
        with self._cond:
            self._link = open_link(self.options, time.monotonic)
            self._rx.clear()
        self.is_open = True

    def close(self) -> None:
        with self._cond:
            self.is_open = False
            self._cond.notify_all()
        super().close()

    def from_url(self, url: str) -> SimOptions:
        """Parse ``sim://?key=value&...``; every mistake names the key and what it accepts."""
        parts = urllib.parse.urlsplit(url)
        if parts.scheme != "sim" or parts.netloc or parts.path not in ("", "/"):
            raise SerialException(f"expected sim://[?key=value&...], got {url!r}")
        try:
            return SimOptions.from_query(parts.query)
        except ValueError as exc:
            raise SerialException(f"bad sim:// option: {exc}") from None

    def _reconfigure_port(self) -> None:
        """Nothing to configure: the simulator has no line settings to change."""

    # -- data -------------------------------------------------------------

    def _pump(self) -> None:
        """Move every byte that has reached the host into the read buffer (lock held)."""
        if self._link is not None:
            self._rx += self._link.read()

    def _link_or_raise(self) -> SimLine[Simulator]:
        if not self.is_open or self._link is None:
            raise PortNotOpenError()
        return self._link

    @property
    def in_waiting(self) -> int:
        self._link_or_raise()
        with self._cond:
            self._pump()
            return len(self._rx)

    @property
    def out_waiting(self) -> int:
        """Written bytes the paced line has not yet delivered to the robot."""
        link = self._link_or_raise()
        with self._cond:
            self._pump()
            return len(link.to_device)

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes; blocks per ``timeout`` (None: until all arrive, 0: never)."""
        self._link_or_raise()
        timeout = self.timeout
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            self._cancelled = False
            while True:
                self._pump()
                if len(self._rx) >= size or self._cancelled or not self.is_open:
                    break
                wait = self._wait_time(deadline)
                if wait is not None and wait <= 0:
                    break
                self._cond.wait(wait)
            data = bytes(self._rx[:size])
            del self._rx[:size]
        return data

    def _wait_time(self, deadline: float | None) -> float | None:
        """Until the read deadline or the link's next event, whichever is first; None is forever."""
        now = time.monotonic()
        due = self._link.next_due() if self._link else None
        waits = [max(due - now, _MIN_WAIT_S)] if due is not None else []
        if deadline is not None:
            waits.append(deadline - now)
        return min(waits, default=None)

    def write(self, data: ReadableBuffer) -> int:
        link = self._link_or_raise()
        raw: bytes = to_bytes(data)
        with self._cond:
            link.write(raw)
            self._cond.notify_all()
        return len(raw)

    def flush(self) -> None:
        """Wait until the paced line has delivered every written byte, like tcdrain().

        A no-op once closed, because ``io.RawIOBase.close`` calls it.
        """
        link = self._link
        if not self.is_open or link is None:
            return
        with self._cond:
            last = link.to_device.last_time()
        if last is not None:
            time.sleep(max(0.0, last - time.monotonic()))

    def reset_input_buffer(self) -> None:
        """Discard what has arrived; bytes still on the line will arrive later, as on a UART."""
        self._link_or_raise()
        with self._cond:
            self._pump()
            self._rx.clear()

    def reset_output_buffer(self) -> None:
        """Abort written bytes the paced line has not yet delivered."""
        link = self._link_or_raise()
        with self._cond:
            link.to_device.clear()

    def cancel_read(self) -> None:
        with self._cond:
            self._cancelled = True
            self._cond.notify_all()

    def cancel_write(self) -> None:
        """Writes never block, so there is nothing to cancel."""
