"""Tests of the simulator: world, renderer, metrics, scenario files, closed loop, CLI."""
