"""Where the readings go beyond the terminal: the Foxglove bridge, MCAP and CSV recordings."""
