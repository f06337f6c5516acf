"""Shells: what owns time and I/O around the pure runtime core (the real-time loop)."""
