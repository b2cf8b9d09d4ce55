"""The fleet: robots and operators on several hosts, over Eclipse Zenoh (the zenoh extra)."""
