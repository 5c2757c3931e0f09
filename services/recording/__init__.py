"""MCAP recordings: reading and writing, the recorder service."""
