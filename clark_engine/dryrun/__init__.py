"""The dry run: every agent's real runtime against a simulated fleet, and its report."""
