"""What a finished run's logs say: where they are, and the thesis's latency tables."""
