"""Synthetic data and ray-traced ground truth (Mitsuba 3)."""
