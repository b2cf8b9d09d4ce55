"""The fleet: robots and operators on several hosts, over Eclipse Zenoh (the ``hcrctl[zenoh]`` extra)."""
