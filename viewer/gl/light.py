"""One area light in the engine: its parameters, what the engine derived from them (the shadow
frame, how much it can contribute), which of its per-light passes are stale, and the GL resources
it owns (its shadow map and the atlases of its convolutional shadow map)."""

from __future__ import annotations

from dataclasses import dataclass, field

import moderngl
import numpy as np

from viewer.gl.kit import PassKit
from viewer.gl.prefilter import BlurPlan
from viewer.scene import shadow_space as ss
from viewer.shader_modes import code

# light-pass modes per light (shaders/light_pass.frag.glsl): what the light atlas holds for it
PASS_OFF, PASS_HARD, PASS_SOFT, PASS_UNSHADOWED = (code("PASS", n) for n in ("off", "hard", "soft", "unshadowed"))
PER_LIGHT_PASSES = ("shadow_map", "csm_basis", "prefilter", "light_pass")


@dataclass
class Light:
    direction: np.ndarray
    sigma: float
    intensity: np.ndarray
    frame: ss.LightFrame | None = None  # the shadow map's orthographic frame
    facing: float = 0.0  # max n.l over the mask's normals
    bound: float = 0.0  # max intensity x facing x the scene's response bound: >= any pixel's value
    active: bool = True  # False: it cannot contribute, every pass skips it (its stale passes wait)
    stale: set = field(default_factory=lambda: set(PER_LIGHT_PASSES))  # per-light passes to redo
    pass_mode: int = PASS_OFF  # light-pass mode the light atlas currently holds for this light
    tile: tuple = (0, 0)  # origin of this light's group tile in the light atlas
    slot: int = 0  # plane of the light atlas (light index % LIGHTS_PER_PASS)
    # resources, made on first use
    shadow_map: moderngl.Texture | None = None
    shadow_fbo: moderngl.Framebuffer | None = None
    plan: BlurPlan | None = None  # how its basis is pre-filtered (from sigma)
    filtered: moderngl.Texture | None = None  # pre-filtered basis atlas (one of ``work``)
    work: dict = field(default_factory=dict)  # intermediate atlases: slot -> (texture, framebuffer)

    def ensure_shadow_map(self, kit: PassKit, resolution: int, depth: moderngl.Renderbuffer):
        if self.shadow_map is None:
            self.shadow_map = kit.texture((resolution, resolution), 1)
            self.shadow_fbo = kit.ctx.framebuffer(color_attachments=[self.shadow_map], depth_attachment=depth)

    def work_atlas(self, kit: PassKit, size, slot: str):
        """This light's own intermediate atlas ``slot`` of ``size`` (kept per light so that every
        stage can run for all lights before the next starts: llvmpipe then waits once per stage)."""
        entry = self.work.get(slot)
        if entry is None or entry[0].size != tuple(size):
            if entry is not None:
                entry[1].release()
                entry[0].release()
            tex = kit.texture(size, 4, linear=(slot == "filtered"))
            entry = self.work[slot] = (tex, kit.ctx.framebuffer(color_attachments=[tex]))
        return entry

    def release(self):
        for res in [self.shadow_fbo, self.shadow_map] + [r for entry in self.work.values() for r in reversed(entry)]:
            if res is not None:
                res.release()
        self.work.clear()


def frame_lights(lights: list[Light], resources, resolution: int, terms: int):
    """Each light's shadow frame and facing (its best n.l over the person), after it turned;
    ``resources``: the scene's :class:`viewer.gl.scene_resources.SceneResources`."""
    dirs = np.array([l.direction for l in lights])
    frames = ss.light_frames(resources.caster_points, dirs, resolution, terms, sphere=resources.sphere)
    for l, frame, f in zip(lights, frames, resources.facing(dirs)):
        l.frame, l.facing = frame, max(float(f), 0.0)


def update_activity(lights: list[Light], response_bound: float, diffuse_bound: float, leave_out: bool,
                    skip_threshold: float) -> bool:
    """Which lights take part: a light is skipped when even its upper bound (diffuse + specular
    peak) stays below ``skip_threshold`` of the scene's diffuse level (the sum of the lights'
    diffuse bounds). Returns whether any light's activity changed."""
    peaks = [float(np.max(l.intensity)) * l.facing for l in lights]  # max I x max n.l
    for l, peak in zip(lights, peaks):
        l.bound = peak * response_bound
    level = sum(peaks) * diffuse_bound
    level = level if level > 0 else sum(l.bound for l in lights)
    changed = False
    for l in lights:
        active = not leave_out or (l.bound > 0.0 and l.bound >= skip_threshold * level)
        if active != l.active:
            l.active, changed = active, True
    return changed


def needed_pass(l: Light, visibility: str, inspected: Light | None, soft_is_hard: bool) -> int:
    """The light-pass mode the shown visibility needs for this light: no shadow map when no shadows
    are shown, no filtering unless the soft visibility is shown (``soft_is_hard``: sigma ~ 0, its soft
    visibility is its hard one). ``inspected``: the light the shadow view shows, whose soft
    visibility is needed even when no shadows are shown."""
    if not l.active:
        return PASS_OFF
    if visibility == "none" and inspected is l:
        visibility = "soft"
    if visibility == "none":
        return PASS_UNSHADOWED
    if visibility == "hard" or soft_is_hard:
        return PASS_HARD
    return PASS_SOFT  # soft, and refined (whose network reads the hard and soft visibility)
