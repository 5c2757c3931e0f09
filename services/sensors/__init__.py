"""Sensor processes: simulated radars, ASTERIX file and UDP readers, replay of recordings."""
