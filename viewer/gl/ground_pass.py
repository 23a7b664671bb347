"""9. The ground shadow (ground_shadow.frag.glsl): the person's shadow on the ground plane at the
feet (:mod:`viewer.scene.ground`: through the feet's contacts, or level at the person's lowest point), a
shadow catcher lit by the same lights, at half the work resolution (the shadow of a person on the
ground is soft; the display samples it bilinearly), with each foot's contact shadow. What it
holds, per pixel, is the share of the plane's light the person takes away (RGB); the display and
frame composite multiply the background by one minus it (``Look.ground``). Runs only while the
ground is shown."""

from __future__ import annotations

import math

import moderngl
import numpy as np

from viewer.gl.kit import PassKit, band_box
from viewer.gl.light import PASS_HARD, PASS_OFF, PASS_SOFT, Light
from viewer.gl.light_pass import BANDS, LIGHTS_PER_PASS, LightShadingPass
from viewer.gl.scene_resources import SceneResources
from viewer.gl.work_budget import draw_bands
from viewer.scene.ground import CONTACT_BOUND, MAX_CONTACT_POINTS, GroundPlane, contact_spread

GROUND_PIXELS = 100_000


class GroundShadowPass:
    name = "ground_shadow"
    # what the lights' visibility and weights are made of (the light pass's output covers their
    # direction, shadow map, sigma and mode)
    inputs = ("light_pass", "intensity", "activity", "ground", "visibility")

    def __init__(self, kit: PassKit, scene: SceneResources, light_pass: LightShadingPass, camera, plane: GroundPlane,
                 scale: int = 2):
        self.kit, self.scene, self.light_pass = kit, scene, light_pass
        # at most GROUND_PIXELS: its cost per pixel is every light's soft visibility and the feet's
        # contact points (a 980x654 work frame at half size spent 130-180 ms of a 350 ms frame here)
        scale = max(scale, math.ceil(math.sqrt(camera.width * camera.height / GROUND_PIXELS)))
        w, h = max(camera.width // scale, 1), max(camera.height // scale, 1)
        self.size = (w, h)
        self.center = (w / 2.0, h / 2.0)
        self.focal_px = camera.focal_px * w / camera.width
        self.plane = plane
        # where the contact points can darken the plane: within CONTACT_BOUND of them
        pts = plane.contact_points[:, :3].astype(np.float64)
        centre = pts.mean(axis=0) if len(pts) else np.zeros(3)
        radius = float(np.linalg.norm(pts - centre, axis=1).max()) + CONTACT_BOUND if len(pts) else 0.0
        self.contact_bound = (*(float(v) for v in centre), radius)
        self._next = None  # a budgeted run under way: the next (group, band)
        self.texture = kit.texture(self.size, 4, linear=True)
        self.fbo = kit.ctx.framebuffer(color_attachments=[self.texture])

    def restart(self):
        """Something changed since a budgeted run was left part-way: it starts again from its first group."""
        self._next = None

    def run(self, lights: list[Light], shadows: str, work=None) -> bool:
        """``shadows``: the look's shadow mode (none: no shadow on the ground either). With ``work``
        (a budgeted render, :class:`viewer.gl.work_budget.WorkBudget`) each band of rows of a group of
        lights is a unit (a group is ~50 ms idle, twice that beside a busy process): False when the budget
        ran out first (the bands drawn add up in the texture; the next call goes on from the next band,
        the engine calling :meth:`restart` first when anything changed meanwhile)."""
        kit = self.kit
        if work is None or self._next is None:
            self._next = (0, 0)
        first = self._next
        with kit.timed(self.name):
            self.fbo.use()
            if first == (0, 0):
                self.fbo.clear(0.0, 0.0, 0.0, 0.0)
            intensity = np.array([l.intensity for l in lights], np.float64).reshape(-1, 3)
            up = np.array([max(float(np.dot(l.direction, self.plane.normal)), 0.0) for l in lights])
            e0 = (intensity * up[:, None]).sum(axis=0)  # the plane's unshadowed irradiance (RGB)
            if shadows == "none" or not self.plane.below_camera or not np.any(e0 > 0.0):
                self._next = None
                return True
            share = np.where(e0 > 0.0, intensity * up[:, None] / np.where(e0 > 0.0, e0, 1.0), 0.0).astype("f4")
            prog = kit.programs.get("fullscreen.vert.glsl", "ground_shadow.frag.glsl", self.light_pass.sources, **self.light_pass.defines,
                                    MAX_CONTACT_POINTS=MAX_CONTACT_POINTS)
            prog["ground_normal"] = tuple(float(v) for v in self.plane.normal)
            prog["ground_offset"] = self.plane.offset
            prog["focal_center_px"] = self.center
            prog["focal_px"] = self.focal_px
            points = np.zeros((MAX_CONTACT_POINTS, 4), "f4")
            points[:len(self.plane.contact_points)] = self.plane.contact_points
            prog["contact_points"].write(points.tobytes())
            prog["contact_count"] = len(self.plane.contact_points)
            prog["contact_spread"] = contact_spread(len(lights))
            prog["contact_bound"] = self.contact_bound
            kit.ctx.enable(moderngl.BLEND)
            kit.ctx.blend_func = moderngl.ONE, moderngl.ONE
            try:
                for g in range(first[0], len(lights), LIGHTS_PER_PASS):
                    group = lights[g:g + LIGHTS_PER_PASS]
                    # the shadows shown: a light pass that also holds the soft visibility (Engine.render's
                    # soft_planes) casts hard shadows on the ground when hard shadows are shown
                    modes = [PASS_OFF if not l.active else PASS_HARD if shadows == "hard" and l.pass_mode == PASS_SOFT
                             else l.pass_mode for l in group]
                    if not any(m in (PASS_HARD, PASS_SOFT) for m in modes):
                        continue  # no shadows from these lights (or none shown)
                    self.light_pass.bind_lights(prog, group, modes)
                    block = np.zeros((LIGHTS_PER_PASS, 3), "f4")
                    block[:len(group)] = share[g:g + len(group)]
                    prog["light_share"].write(block.tobytes())

                    def draw(band):
                        self.fbo.scissor = band_box(self.size, band, BANDS) if band is not None else None
                        kit.fullscreen(prog)

                    # a group after the call's first starts with a unit of its own
                    left = draw_bands(work, first[1] if g == first[0] else 0, BANDS, "ground_band", draw,
                                      check_first=g != first[0])
                    if left is not None:
                        self._next = (g, left)
                        return False
            finally:
                self.fbo.scissor = None
                kit.ctx.disable(moderngl.BLEND)
                kit.ctx.blend_func = moderngl.DEFAULT_BLENDING
        self._next = None
        return True

    def read(self) -> np.ndarray:
        """(h, w, 3) float32: the share of the ground's light the person takes away."""
        return self.kit.read(self.texture, 4)[..., :3]

    def release(self):
        self.fbo.release()
        self.texture.release()
