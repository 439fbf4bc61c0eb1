"""Tests of the actuation layer."""
