"""Real ArduPilot SITL: its processes and the pace a dry run holds them to."""
