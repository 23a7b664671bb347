"""Quality presets: the number of area lights and the engine's options, chosen from the measured
error-versus-time Pareto front of ``relight bench report`` (docs/results.md says which points
and why). ``balanced`` is the default of the engine (``EngineOptions()``), the viewer and
``relight render``; ``interactive`` renders every frame of a drag at full quality (>= 10 frames a
second at 512^2 on llvmpipe); ``final`` is for saved frames and videos.
"""

from __future__ import annotations

from dataclasses import dataclass

from .gl.engine import EngineOptions


@dataclass(frozen=True)
class Preset:
    name: str
    lights: int  # area lights fitted to the map
    options: EngineOptions
    rule: str  # how it is chosen from the front (relight bench report applies it)


PRESETS = {
    "interactive": Preset("interactive", 8, EngineOptions(shadow_resolution=256, terms=2),
                          "the lowest error among settings whose full frame takes <= 90 ms at 512^2"),
    "balanced": Preset("balanced", 16, EngineOptions(),
                       "the fastest setting whose error is within 5 % of the 64-light setting's"),
    "final": Preset("final", 32, EngineOptions(shadow_resolution=1024, terms=8),
                    "the lowest error among settings whose full frame takes <= 1 s at 512^2"),
}
DEFAULT_PRESET = "balanced"


def preset(name: str) -> Preset:
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}") from None
