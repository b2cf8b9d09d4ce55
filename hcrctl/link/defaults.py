"""The link's defaults, said once: line rate, reply timeout, read retries, poll rate and the deadman.

The client's keyword defaults, the connection context's fields and the CLI's
option table each said 115200 / 0.5 / 2 on their own, free to drift apart. A
module of its own, like ``stopwait``, so the option table can import them
without importing the client. The baud rate is the default protocol
profile's: the profile is where a firmware's line rate lives.
"""

from ..protocol.profiles import DEFAULT

#: Serial line rate, bit/s, of the default protocol profile.
BAUD: int = DEFAULT.baud
#: Seconds to wait for a reply before a retry (``--timeout``).
REPLY_TIMEOUT_S: float = 0.5
#: Extra attempts of a read that got no reply (``--retries``).
RETRIES: int = 2
#: Sweeps a second of the polling commands (``--rate``: watch, plot, record, bridge, ros2, fleet serve).
RATE_HZ: float = 10.0
#: The slowest and the fastest sweep rate asked of a poller (``--rate`` of every polling command, the ROS 2
#: node's ``rate`` parameter): below it a poll period would outlast any wait a person makes for a reading.
MIN_RATE: float = 0.1
MAX_RATE: float = 1000.0
RATE_RANGE: tuple[float, float] = (MIN_RATE, MAX_RATE)
#: How long motion runs without a fresh command before it is stopped (``--deadman``): teleop's keys, the
#: bridge's and the ROS 2 node's /cmd_vel and the fleet driver's messages share it.
DEADMAN_S: float = 0.5
#: The deadman's range: below it a terminal's own key repeat could not keep up; above it, no deadman.
DEADMAN_RANGE: tuple[float, float] = (0.05, 10.0)
