"""The simulated ArduPilot: what a dry run's vehicles fly with, met only as MAVLink bytes."""
