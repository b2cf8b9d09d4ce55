"""Recordings: topic messages written to MCAP and CSV files, and logs exported to them."""
