"""The Foxglove front end: the robot served on the Foxglove WebSocket protocol (`hcrctl bridge`)."""
