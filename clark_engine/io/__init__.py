"""Adapters between the runtime's typed events and commands and the bytes of real devices."""
