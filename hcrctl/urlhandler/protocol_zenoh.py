"""``zenoh://NAME``: a fleet robot as a pyserial port (thin: the logic is ``fleet.remote``).

What the Robot writes goes to ``RemoteLink.write`` as whole frames, never as
raw bytes to the robot; the replies the robot side sends back wait in a read
buffer, and a reader blocked in ``read()`` wakes as soon as one arrives.
Where the fleet is comes from the Connection (``reach=``, passed through
``serial_for_url``'s keywords), not from global state; without it, the
default router on loopback. Zenoh is imported on ``open()``, not on import:
pyserial reports a failed import of a handler as "protocol not known".
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Any

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes  # type: ignore[attr-defined]

from ..fleet.remote import Reach, RemoteLink
from ..fleet.remote.link import robot_name

# types-pyserial leaves out serialutil.to_bytes, which pyserial 3.5 has and its own handlers use.
from .cable import HealthyCable

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer


class Serial(HealthyCable, SerialBase):
    """A serial port whose other end is a robot served to the fleet (``hcrctl fleet serve``)."""

    def __init__(self, *args: Any, reach: Reach | None = None, **kwargs: Any) -> None:
        self._cond = threading.Condition()
        self._rx = bytearray()
        self._cancelled = False
        self._gone: str | None = None
        self._reach = reach or Reach()
        self.link: RemoteLink | None = None
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self.port is None:
            raise SerialException("Port must be configured before it can be used.")
        link = RemoteLink(robot_name(self.port), self._reach, self._deliver, self._lost)
        link.open()
        self.link, self._gone = link, None
        self.is_open = True

    def close(self) -> None:
        link, self.link = self.link, None
        with self._cond:
            self.is_open = False
            self._cond.notify_all()
        if link is not None:
            link.close()
        super().close()

    def _reconfigure_port(self) -> None:
        """Nothing to configure: the robot side owns its serial line's settings."""

    # -- what the robot side sends ------------------------------------------------------

    def _deliver(self, data: bytes) -> None:
        with self._cond:
            self._rx += data
            self._cond.notify_all()

    def _lost(self, why: str) -> None:
        with self._cond:
            self._gone = why
            self._cond.notify_all()

    def _link(self) -> RemoteLink:
        if not self.is_open or self.link is None:
            raise PortNotOpenError()
        return self.link

    @property
    def in_waiting(self) -> int:
        self._link()
        with self._cond:
            return len(self._rx)

    @property
    def out_waiting(self) -> int:
        return 0

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes; blocks per ``timeout``; raises once the robot has left the fleet."""
        self._link()
        deadline = None if self.timeout is None else time.monotonic() + self.timeout
        with self._cond:
            self._cancelled = False
            while len(self._rx) < size and not self._cancelled and self.is_open and self._gone is None:
                wait = None if deadline is None else deadline - time.monotonic()
                if wait is not None and wait <= 0:
                    break
                self._cond.wait(wait)
            if not self._rx and self._gone is not None:
                raise SerialException(self._gone)
            data = bytes(self._rx[:size])
            del self._rx[:size]
        return data

    def write(self, data: ReadableBuffer) -> int:
        raw: bytes = to_bytes(data)
        link = self._link()
        if self._gone is not None:
            raise SerialException(self._gone)
        link.write(raw)
        return len(raw)

    def flush(self) -> None:
        """Every write has been handed to Zenoh by the time it returns."""

    def reset_input_buffer(self) -> None:
        with self._cond:
            self._rx.clear()

    def reset_output_buffer(self) -> None:
        """Nothing waits to be sent."""

    def cancel_read(self) -> None:
        with self._cond:
            self._cancelled = True
            self._cond.notify_all()

    def cancel_write(self) -> None:
        """Writes never wait on a line, so there is nothing to cancel."""

    def why_no_reply(self, error: Any) -> Any:
        """A timeout of the Robot's, with what the robot side said (see ``RemoteLink.why_no_reply``)."""
        return error if self.link is None else self.link.why_no_reply(error)
