"""Benchmarks: commands that print figures and save JSON (``relight bench ...``)."""
