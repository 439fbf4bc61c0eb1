"""Supervisor tests: filter, events, state machine, watchdog, limiter, loop."""
