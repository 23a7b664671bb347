"""The methods ``relight bench report`` compares, each rendering a scene under a lighting and timed
on the same machine in the same run.

- ``engine``: the GL engine (area lights, shadow maps, soft shadows) at one setting of its knobs:
  number of lights, shadow-map resolution, mesh decimation, the soft shadows (the paper's CSM with
  its Fourier terms M and prefilter, or contact-hardening PCSS), and the leave-out policy;
- ``directional`` (baseline): the same N fitted lights as directional lights with hard shadows only
  (sigma 0: shadow maps, no convolutional shadow maps);
- ``sh`` (baseline): second-order spherical-harmonics lighting of the turned map, no shadows, no
  specular (:mod:`viewer.lighting.sh`, numpy);
- ``twin`` (baseline): the torch twin, the paper's own way of computing the engine's image (CPU).

Times: ``full`` is a frame after the lighting turned (every light moved: shadow maps, filtering,
shading, composite); ``update`` is a frame after one light was edited (the brightest light's sigma
x 1.2 and intensity x 1.1), what a slider drag costs. The SH and twin baselines cache nothing, so
their update is a full frame.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from viewer.gl import Engine, EngineOptions
from viewer.gl.soft import soft_method
from viewer.lab.bench.engine import frame_seconds
from viewer.scene.area_lights import AreaLights

KINDS = ("engine", "directional", "sh", "twin")


@dataclass(frozen=True)
class Method:
    kind: str = "engine"
    lights: int = 16
    shadow_resolution: int = 512
    shadow_step: int = 0  # 0: the engine's automatic decimation
    terms: int = 4
    prefilter: str = "pyramid"
    leave_out: bool = True
    sigma_scale: float = 1.0  # the fitted sigmas times this (how much softness the scenes want)
    soft: str = "pcss"  # the soft shadows: "pcss" (contact-hardening, the default) or "csm" (terms and prefilter apply)

    def __post_init__(self):
        if self.soft == "pcss":  # terms and prefilter mean nothing there: one PCSS setting, one label
            object.__setattr__(self, "terms", 4)
            object.__setattr__(self, "prefilter", "pyramid")

    @staticmethod
    def from_preset(preset) -> Method:
        o = preset.options
        return Method("engine", preset.lights, o.shadow_resolution, o.shadow_step, o.terms, o.prefilter, o.leave_out,
                      soft=o.soft)

    def options(self) -> EngineOptions:
        return EngineOptions(shadow_resolution=self.shadow_resolution, shadow_step=self.shadow_step, terms=self.terms,
                             prefilter=self.prefilter, leave_out=self.leave_out, soft=self.soft)

    @property
    def uses_lights(self) -> bool:
        return self.kind != "sh"

    @property
    def label(self) -> str:
        if self.kind == "sh":
            return "SH order 2, no shadows"
        if self.kind == "directional":
            return f"{self.lights} directional, hard shadows (SM {self.shadow_resolution})"
        step = "auto" if self.shadow_step == 0 else str(self.shadow_step)
        soft = "PCSS" if self.soft == "pcss" else f"M={self.terms} {self.prefilter}"
        text = f"N={self.lights} SM {self.shadow_resolution} step {step} {soft}"
        if not self.leave_out:
            text += " leave-out off"
        if self.sigma_scale != 1.0:
            text += f" sigma x{self.sigma_scale:g}"
        return ("torch twin " if self.kind == "twin" else "") + text


def edited(lights: AreaLights, toggle: bool) -> AreaLights:
    """The brightest light's sigma x 1.2 and intensity x 1.1 (or back, when ``toggle`` is False)."""
    k = lights.brightest
    sigma, intensity = lights.sigma.copy(), lights.intensity.copy()
    if toggle:
        sigma[k] *= 1.2
        intensity[k] *= 1.1
    return AreaLights(lights.direction, sigma, intensity)


class Renderer:
    """One method bound to one scene: ``image(lights, env)`` is the HDR (H, W, 3) relit image under
    the (already turned) lights and map."""

    def __init__(self, ctx, method: Method, scene):
        self.method, self.scene, self.ctx = method, scene, ctx
        self.engine = None
        self._twin_scene = None
        if method.kind in ("engine", "directional"):
            self.engine = Engine(ctx, scene, method.options())
            self.engine.set_visibility("hard" if method.kind == "directional" else "soft")
        elif method.kind == "twin":
            from viewer.twin.relight import SceneTensors

            self._twin_scene = SceneTensors.from_scene(scene, method.shadow_step, "cpu")

    def _lights(self, lights: AreaLights) -> AreaLights:
        """The lights as this method renders them: sigma 0 for the directional baseline, else the
        fitted sigmas times the method's scale."""
        scale = 0.0 if self.method.kind == "directional" else self.method.sigma_scale
        return lights if scale == 1.0 else AreaLights(lights.direction, lights.sigma * scale, lights.intensity)

    def image(self, lights: AreaLights | None, env=None) -> np.ndarray:
        kind = self.method.kind
        if kind == "sh":
            from viewer.lighting.sh import relight

            return relight(self.scene.albedo, self.scene.normal, self.scene.mask, env)
        if kind == "twin":
            import torch

            from viewer.twin import render as twin_render

            with torch.no_grad():
                out = twin_render(self._twin_scene, self._lights(lights), shadow_resolution=self.method.shadow_resolution,
                                  terms=self.method.terms, soft=soft_method(self.method.soft).twin)
            return out.image.numpy().astype(np.float32)
        self.engine.set_lights(self._lights(lights))
        self.engine.render()
        return self.engine.output.read_work_hdr().copy()  # the maps' resolution, as the reference (a photo's frame is larger)

    def times(self, lights: AreaLights | None, env, repeats: int) -> tuple[list[float], list[float]]:
        """(full frame seconds, update seconds) measured ``repeats`` times each under this lighting."""
        if self.engine is None:  # SH and the twin: every frame is computed from scratch
            full = []
            self.image(lights, env)
            for i in range(repeats):
                t0 = time.perf_counter()
                self.image(lights.rotated(3.0 * (i + 1)) if lights is not None else None,
                           env.rotated(3.0 * (i + 1)) if env is not None else None)
                full.append(time.perf_counter() - t0)
            return full, list(full)
        eng, ctx = self.engine, self.ctx
        eng.set_lights(self._lights(lights))
        eng.render()
        full = [frame_seconds(eng, ctx, self._lights(lights.rotated(3.0 * (i + 1)))) for i in range(repeats)]
        base = self._lights(lights.rotated(3.0 * repeats))
        update = [frame_seconds(eng, ctx, edited(base, i % 2 == 0)) for i in range(repeats)]
        return full, update

    def release(self):
        if self.engine is not None:
            self.engine.release()
            self.engine = None
