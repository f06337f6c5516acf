"""The discrete-event simulator: simulated vehicles, autopilots, radio mesh and payloads."""
