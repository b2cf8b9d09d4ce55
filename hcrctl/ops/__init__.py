"""What the commands do with a robot, without Click: send and describe writes, hold and stop
motion, turn and watch the compass, ping, replay a log. ``cli`` only parses and prints."""
