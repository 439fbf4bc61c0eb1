"""Fault-injection campaigns: many randomized simulated runs, each classified by its outcome."""
