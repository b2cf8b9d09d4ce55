"""Stop the robot however a motion ends, even when the link dropped while it moved.

Every command that sends motion (drive, turn, teleop, replay, hex send) runs
it inside ``stopping()``, which sends stop when the block ends. When that stop
cannot go out because the link is gone (a USB adapter unplugged, a socket
closed), the robot keeps running at its last speed: the controller has no
watchdog. So ``rescue()`` takes over, the one place that knows how:

1. it says at once, on stderr, that the robot was moving and stop could NOT
   be delivered, before any waiting;
2. it keeps re-opening the same port (``Robot.reopen``: the same path, which a
   /dev/serial/by-id link or a recreated node may now resolve to a new device;
   socket:// and rfc2217:// simply reconnect) for ``Robot.stop_wait`` seconds;
3. it sends stop the moment the port opens, then asks the device there to
   answer as the robot does (``answers``): the reply to a read from the
   robot's address, or a frame from that address a streaming firmware sends
   unasked. Whatever now holds the path (another pty that took the number, a
   forwarder whose robot is not back) may have received the stop without
   being the robot, so a silent device is written to again on each re-open
   until it answers or the wait ends;
4. it hands back the one error to exit with, carrying the outcome: "stop
   delivered after 2.4 s" (the robot answered), "stop written to PATH, but
   nothing answered: the robot may still be moving", or "stop NOT delivered:
   the robot may still be moving" (the port never came back).

Ctrl-C (or SIGTERM/SIGHUP) during the wait gives up at once with the NOT
delivered outcome, and the exit status of that signal (130, 143, 129).
A signal that came before the rescue began is the same giving up, said
beforehand: ``rescue(..., ending=NAME)`` tries the port once (a device back
at the path gets its stop) and waits for nothing, so a server told to end
ends at once, its outcome said.
"""

from __future__ import annotations

import contextlib
import os
import queue
import signal
import time
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING

from ..errors import DeviceTimeout, HcrError, LinkLostWhileMoving, NotTheRobot, PortError
from ..errors.status import ExitStatus
from ..errors.terminal import warn
from ..protocol import commands as C
from ..signals import Terminated
from .defaults import BAUD
from .dialects import frame_of, stop_frames

if TYPE_CHECKING:
    from .client import Robot

#: Between two attempts to re-open the port: short, since every moment counts
#: once the device is back, and a missing path is checked without opening it.
RETRY_S = 0.02

StopFrames = Callable[[], Iterable[bytes]]


def stop_frame(robot: Robot, address: int | None = None) -> bytes:
    """Motor power 0x80 0x80 to ``address`` (default the robot's), under its checksum rule and protocol."""
    return frame_of(robot, C.STOP, address)


@contextlib.contextmanager
def stopping(robot: Robot, frames: StopFrames | None = None, *, ending: str | None = None) -> Iterator[None]:
    """Send stop when the block ends, however it ends; rescue it if the link is gone.

    ``frames`` gives the stop frames to send (default: stop to the robot's
    address and to every address its writes moved, ``stop_frames``); it is
    called at the end, so every address moved by then is stopped. When the block raised and stop went out (or nothing had moved),
    the block's error is the news; when stop could not be delivered because
    the link dropped, the rescue's outcome is. ``ending``: as for ``rescue``.
    """
    frames = frames or (lambda: stop_frames(robot))
    try:
        yield
    except BaseException as exc:
        lost = _stop(robot, frames, quiet=True, ending=ending)
        if lost is not None:
            raise lost from exc
        raise
    lost = _stop(robot, frames, quiet=False, ending=ending)
    if lost is not None:
        raise lost


def _stop(robot: Robot, frames: StopFrames, *, quiet: bool, ending: str | None) -> HcrError | None:
    """Send the stop frames; the rescue's outcome if the link was lost while moving."""
    moved = robot.moved
    try:
        robot.stop(frames())
    except Exception:
        if moved and robot.error is not None:
            return rescue(robot, frames, ending=ending)
        if quiet:
            return None
        raise
    return None


def rescue(robot: Robot, frames: StopFrames, *, ending: str | None = None) -> LinkLostWhileMoving:
    """Warn, wait for the port to come back, send stop; the error carrying the outcome.

    ``ending``: the name of a stop signal that already ended the run (a server told to end): the port is
    tried once, with no wait and no warning beforehand, since no one is left to wait for it.
    """
    cause = robot.error or PortError("lost the link", robot.port)
    reopen = robot.reopen or _same_port(robot)
    wait = 0.0 if ending else robot.stop_wait
    started = time.monotonic()
    try:  # a signal from here on is giving up, even one that lands before the warning is out
        if ending is None:
            warn(
                f"lost the link on {robot.port} while the robot was moving: stop could NOT be delivered; "
                f"re-opening {robot.port} for up to {wait:g} s to send it (Ctrl-C gives up)"
            )
        if getattr(reopen, "owned", True):
            robot.close()  # release the dead port (nothing can be sent on it) before re-opening
        took, written, refused = _wait_and_stop(robot.port, reopen, list(frames()), started + wait)
    except KeyboardInterrupt:
        return _not_delivered(cause, "gave up on Ctrl-C", ExitStatus.INTERRUPTED)
    except Terminated as exc:
        return _not_delivered(cause, f"gave up on {signal.Signals(exc.signum).name}", exc.exit_code)
    within = f"when {ending} ended the run" if ending else f"within {wait:g} s"
    if took is None and not written:
        back = "was not back" if ending else "did not come back"
        return _not_delivered(cause, f"{robot.port} {back} {within}", ExitStatus.FAILED)
    if took is None and refused is not None:
        return _not_delivered(
            cause,
            f"{refused.message} ({within})",
            1,
            f"stop sent to {robot.port}, but only what could not prove it is the robot answered: "
            "the robot may still be moving",
        )
    if took is None:
        return _not_delivered(
            cause,
            f"nothing at {robot.port} answered as the robot does {within}: another device may hold the path",
            1,
            f"stop written to {robot.port}, but nothing answered: the robot may still be moving",
        )
    robot.moved = False
    return LinkLostWhileMoving(
        cause,
        f"stop delivered after {took - started:.1f} s",
        delivered=True,
        hint="the robot is stopped; check the cable and the adapter",
    )


def _not_delivered(
    cause: HcrError,
    why: str,
    exit_code: int,
    outcome: str = "stop NOT delivered: the robot may still be moving",
) -> LinkLostWhileMoving:
    error = LinkLostWhileMoving(
        cause,
        outcome,
        delivered=False,
        hint=f"{why}; stop it by hand (power switch), then check the cable",
    )
    error.exit_code = exit_code
    return error


def _wait_and_stop(
    port: str, reopen: Callable[[], Robot], frames: list[bytes], deadline: float
) -> tuple[float | None, bool, NotTheRobot | None]:
    """Re-open until ``deadline``; send ``frames`` on each success until the robot answers.

    When stop reached a device that answered (monotonic; None if none did),
    whether it was written at all (to a device that did not answer), and why
    the last answer was not the robot's, when what answered could not prove it.
    """
    written, refused = False, None
    while True:
        if _may_be_back(port):
            try:
                at, answered = _send_on(reopen, frames)
            except NotTheRobot as exc:
                written, refused = True, exc
            except HcrError:
                pass
            else:
                if answered:
                    return at, True, None
                written = True
        if time.monotonic() >= deadline:
            return None, written, refused
        time.sleep(RETRY_S)


def _may_be_back(port: str) -> bool:
    """A device path is worth opening only once it exists (the missing case stays cheap)."""
    return "://" in port or os.path.exists(port)


def _send_on(reopen: Callable[[], Robot], frames: list[bytes]) -> tuple[float, bool]:
    """Open, write the stops, drain them to the line; when they were written, and whether the robot answered."""
    robot = reopen()
    try:
        robot.stop(frames)
        at = time.monotonic()
        with contextlib.suppress(Exception):
            robot.serial.flush()
        return at, answers(robot)
    finally:
        if getattr(reopen, "owned", True):
            robot.close()


def answers(robot: Robot) -> bool:
    """Whether the device behind ``robot``'s port answers as the robot does (asked once, with its retries).

    A motion command has no reply in either dialect, so the stop itself proves
    nothing: a read is sent to the robot's address, and either its reply (even
    one out of range: it came from there) or any other frame from that address
    counts (a streaming v0.11 firmware sends its bumper and IR frames unasked,
    whatever it was asked). A device
    that only echoes what it is sent (a pty nobody reads, a loopback) does not
    count: an echo is dropped before it is routed.
    """
    probe = next(c for c in C.COMMANDS if c.kind == "read" and robot.profile.has(c.code))
    try:
        reply = robot.sweep([probe]).get(probe.name)
    except NotTheRobot:
        raise  # what answered is not the robot: said so, never "nothing answered"
    except HcrError:  # the link went away again while asking
        return False
    if not isinstance(reply, DeviceTimeout):
        return True
    while True:
        try:
            frame = robot.unsolicited.get_nowait()
        except queue.Empty:
            return False
        if frame.address == robot.address:
            return True


def _same_port(robot: Robot) -> Callable[[], Robot]:
    """For a Robot opened without a Connection: the same port with the same parameters and hooks."""
    from .client import Robot as RobotClass

    baud = getattr(robot.serial, "baudrate", BAUD)

    def reopen() -> Robot:
        again = RobotClass(
            robot.port,
            baud=baud,
            address=robot.address,
            timeout=robot.timeout,
            retries=robot.retries,
            rule=robot.rule,
        )
        for hook in robot.traffic_hooks:
            again.add_traffic_hook(hook)
        return again

    return reopen


class OwedStop:
    """watch's stop key, pressed while the link was down: delivered the moment it is back.

    The dashboard keeps running (its poller re-opens the port by itself), so
    the stop is retried as its loop turns; if watch ends with the stop still
    owed, ``finish`` hands over to ``rescue``, as any other command would.
    """

    def __init__(self) -> None:
        self.since: float | None = None

    def ask(self, robot: Robot | None) -> str:
        """The key was pressed: send stop now, or owe it; what to show in the footer."""
        if _send_stop(robot):
            self.since = None
            return f"stop sent at {time.strftime('%H:%M:%S')}"
        if self.since is None:
            self.since = time.monotonic()
        return "stop NOT delivered: the link is down; it is sent the moment the port is back"

    def deliver(self, robot: Robot | None) -> str | None:
        """Send an owed stop once ``robot`` is connected; a note when it went out."""
        if self.since is None or not _send_stop(robot):
            return None
        took, self.since = time.monotonic() - self.since, None
        return f"stop delivered after {took:.1f} s, at {time.strftime('%H:%M:%S')}"

    def finish(self, current: Robot | None, first: Robot) -> None:
        """At the end: deliver what is owed, or raise ``rescue``'s outcome."""
        if self.since is not None and self.deliver(current) is None:
            raise rescue(first, lambda: [stop_frame(first)])


def _send_stop(robot: Robot | None) -> bool:
    """Stop on a connected robot; whether it went out."""
    if robot is None or not robot.connected:
        return False
    try:
        robot.stop()
    except HcrError:
        return False
    return True
