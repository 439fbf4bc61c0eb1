"""Supervisor: the only path from a lane observation to a motor command.

Filters the slope sum (Kalman, filterpy), runs the fail-safe state machine (transitions) and
watches input ages (the supervised controller); the SafetyGate (`gate.py`) between every
controller and the base latches HALT on physical hazards, zeroes every HALT and limits commands.
Pure logic: every function takes `now`/`dt`; nothing here reads a clock, a camera or a port.
"""
