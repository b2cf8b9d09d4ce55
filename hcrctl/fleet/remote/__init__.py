"""The operator's end of a fleet robot: ``--port zenoh://NAME`` as a link like any other.

Every command talks to a ``Robot`` that writes frames to a serial-like port
and reads replies back. For a fleet robot that port is
``urlhandler.protocol_zenoh``, a thin pyserial handler over ``RemoteLink``
(``link``): each frame the Robot writes is decoded and becomes fleet traffic
(a read query, a write query, the drive lease and ``cmd_vel``, a stop), and
the reply frames the robot side sends back are what the Robot reads. Raw bytes
are never tunnelled: anything that is not a request of the command table is
refused. ``lease`` holds the drive lease while motion runs; ``reframe`` lays
a reply out in the dialect the local Robot speaks.

A package (not ``remote_*.py`` modules) so that all of it stays in the link
layer, where the URL handler may import it.
"""

from __future__ import annotations

from .link import Reach, RemoteLink

__all__ = ["Reach", "RemoteLink"]
