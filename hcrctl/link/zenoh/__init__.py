"""The operator's end of a fleet robot: ``--port zenoh://NAME`` as a link like any other.

Every command talks to a ``Robot``. For a fleet robot its port is a carrier
(``link.carrier``): ``RemoteLink`` (``link``) takes each request of the
command table the Robot sends and makes it fleet traffic (a read query, a
write query, the drive lease and ``cmd_vel``, a stop), and hands the robot
side's answers back as replies, content in the table's layout. Raw bytes are
never tunnelled. ``lease`` holds the drive lease while motion runs.

A package (not ``remote_*.py`` modules) so that all of it stays in the link
layer, where ``link.carrier`` names it.
"""

from __future__ import annotations

from .remote import RemoteLink, open_carrier

__all__ = ["RemoteLink", "open_carrier"]
