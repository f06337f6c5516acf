"""The runtime core: one agent's behaviour on a fixed-rate loop, pure and clock-free.

``AgentRuntime`` is built from a compiled config; shells (a real-time loop, the
simulator) deliver typed events and call ``tick`` at ``loop_hz``, and carry out
the typed commands it returns.
"""
