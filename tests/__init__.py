"""Lanewarden test suite (a package, so that tests/<layer>/ never shadows the <layer> package)."""
