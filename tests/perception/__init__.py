"""Perception tests: synthetic frames with known geometry, real frames, the detect CLI."""
