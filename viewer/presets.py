"""Quality presets: the number of area lights and the engine's options, chosen from the measured
error-versus-time Pareto front of ``relight bench report`` (docs/results.md says which points
and why). ``balanced`` is the default of the engine (``EngineOptions()``), the viewer and
``relight render``; ``interactive`` renders every frame of a drag at full quality (>= 10 frames a
second at 512^2 on llvmpipe); ``final`` is for saved frames and videos.
"""

from __future__ import annotations

from dataclasses import dataclass

from .gl.options import EngineOptions


@dataclass(frozen=True)
class Preset:
    name: str
    lights: int  # area lights fitted to the map
    options: EngineOptions
    rule: str  # how it is chosen from the front (relight bench report applies it)

    @property
    def summary(self) -> str:
        return f"{self.lights} lights, shadow maps {self.options.shadow_resolution}, M = {self.options.terms}"


# The 2026-11-22 report (docs/results.md) picked, by these rules: interactive = 8 lights (67 ms, RMSE
# 0.0658), final = 64 lights (413 ms, 0.0588), both with the default options; for balanced, 16
# lights with mesh step 2 (157 ms, 0.0617, +4.9 % over 64 lights). Balanced keeps the automatic
# decimation (3 per 512 pixels, 122 ms, 0.0619, +5.2 %): a fixed step does not scale with the image
# (step 2 at 1024^2 draws 9 times the automatic triangles) and the error differs by 0.3 %.
PRESETS = {
    "interactive": Preset("interactive", 8, EngineOptions(),
                          "the lowest error among settings whose full frame takes <= 90 ms at 512^2"),
    "balanced": Preset("balanced", 16, EngineOptions(),
                       "the fastest setting whose error is within 5 % of the 64-light setting's"),
    "final": Preset("final", 64, EngineOptions(),
                    "the lowest error among settings whose full frame takes <= 1 s at 512^2"),
}
DEFAULT_PRESET = "balanced"


def preset(name: str) -> Preset:
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}") from None
