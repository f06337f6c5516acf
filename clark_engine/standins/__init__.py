"""Stand-ins for hardware, served for ``clark run``: an autopilot, a radio network, a payload."""
