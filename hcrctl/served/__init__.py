"""The served-robot runtime every server front end shares: one polled link, one motion governor, one end.

``ServedRobot`` composes, once, what serving a robot to the network needs:
the loopback warning, the signals as a flag, the feed (``served.feed.Feed``),
the governor with the bumper rule, the link watch, the final stop to the
robot driven then, the end and the summary. A front end (the Foxglove
server, the Zenoh fleet, a ROS 2 node) is a ``FrontEnd``: it publishes what
the feed yields, turns what its clients send into offers to the governor,
and tells its own sources why motion stopped, seeing the runtime only
through ``view.RuntimeView``. ``runtime`` says how one plugs in; the table
``frontends`` names them all and composes a command's run from them.
"""
