"""skyfuse services: simulator/recording commands, sensors, fusion, recorder, replay, CLI."""
