"""``hcrctl ros2``: the robot as a ROS 2 node over DDS (Cyclone DDS's Python binding, the ros2 extra).

Imported only by that command: nothing else in hcrctl loads cyclonedds.
"""
