"""Quality presets: the number of area lights and the engine's options, chosen from the measured
error-versus-time Pareto front of ``relight bench report`` (docs/results/results.md says which points
and why). ``balanced`` is the default of the engine (``EngineOptions()``), the viewer and
``relight render``; ``interactive`` renders every frame of a drag at full quality (>= 10 frames a
second at 512^2 on llvmpipe); ``final`` is for saved frames and videos.
"""

from __future__ import annotations

from dataclasses import dataclass

from viewer.gl.options import EngineOptions


@dataclass(frozen=True)
class Preset:
    name: str
    lights: int  # area lights fitted to the map
    options: EngineOptions
    rule: str  # how it is chosen from the front (relight bench report applies it)

    @property
    def summary(self) -> str:
        return f"{self.lights} lights, shadow maps {self.options.shadow_resolution}, M = {self.options.terms}"


# The 2026-11-24 report (docs/results/results.md, contact-hardening soft shadows the default) picked, by
# these rules: final = 64 lights with shadow maps of 1024 (416 ms, RMSE 0.0530), shipped as such;
# interactive = 16 lights with mesh step 4 (88 ms, 0.0565), and balanced = 32 lights (156 ms, 0.0543,
# +2.4 % over 64 lights). Interactive ships 16 lights with shadow maps of 256 (80 ms, 0.0570): the
# run before on the same code picked it (timings move by 10-20 % between runs on this machine), and
# a fixed mesh step does not scale with the image. Balanced keeps 16 lights with shadow maps of 512
# (97 ms, 0.0563, +5.6 %, inside the 10 % target): 32 lights would double every map's light fit
# (the viewer fits a new map while the user waits) and the bundled maps ship 16-light files.
PRESETS = {
    "interactive": Preset("interactive", 16, EngineOptions(shadow_resolution=256),
                          "the lowest error among settings whose full frame takes <= 90 ms at 512^2"),
    "balanced": Preset("balanced", 16, EngineOptions(),
                       "the fastest setting whose error is within 5 % of the 64-light setting's"),
    "final": Preset("final", 64, EngineOptions(shadow_resolution=1024),
                    "the lowest error among settings whose full frame takes <= 1 s at 512^2"),
}
DEFAULT_PRESET = "balanced"


def preset(name: str) -> Preset:
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}") from None
