"""The mutation run for the safety rules (run.py, mutants.toml): see DEVELOPERS.md."""
