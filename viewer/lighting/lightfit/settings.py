"""The sizes of a light fit's views and its progress reports (no torch here: the default fits and the command
line read them)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FitSettings:
    sphere_resolution: int = 64  # sphere view (smooth shading: 64 px resolve it)
    plane_resolution: int = 96  # plane views (shadows)
    shadow_resolution: int = 128  # shadow maps of the fitted lights on the plane views
    samples: int = 1024  # map samples of the reference (accuracy in docs/lights.md)
    terms: int = 4  # CSM Fourier terms


DEFAULT_SETTINGS = FitSettings()  # frozen: one default shared by every call


def report(progress, stage, done, total):
    """Tell an optional ``progress(stage, done, total)`` callback how far a stage is."""
    if progress is not None:
        progress(stage, done, total)
