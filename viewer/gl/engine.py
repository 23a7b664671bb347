"""The GL engine: renders a scene bundle under a set of area lights, redoing only what changed.

The engine only orders the passes and tracks what changed; each pass is an object that owns its GL
resources and names, in ``inputs``, what makes its result stale (docs/engine.md's cache table is
these declarations):

  per light (each light owns its shadow map and CSM atlases, viewer/gl/light.py)
    1 ShadowMapPass      inputs: direction              (shadow_passes.py)
    2 CsmBasisPass       inputs: shadow_map, sigma
    3 PrefilterPass      inputs: csm_basis
    4 LightShadingPass   inputs: direction, shadow_map, prefilter (CSM) or sigma (PCSS: no 2 and 3); four lights per
                         pass (light_pass.py)
  for the frame
    5 CompositePass      inputs: light_pass, intensity, activity, visibility, refined_visibility, terms
    6 DisplayPass        inputs: composite (mask's box); display, view, environment (whole image)
  a scene with a frame layer (frame_pass.py), in place of 6
    7 FrameBackgroundPass  inputs: background, environment
      FrameMipmapsPass     inputs: composite, view
    8 FrameCompositePass   inputs: composite (matte's box); display, view, environment (whole frame)
  the inspection views (InspectPass) draw in place of 6 / 8.
  with Look.ground (ground_pass.py), before 6 / 8
    9 GroundShadowPass   inputs: light_pass, intensity, activity, ground, visibility; 6 and 8 redraw the
                         whole image when it ran

Reading results back is the other half of the interface (outputs.py, a mixin); the final picture,
an image or a photo's frame, is one object with one interface (picture.py). When a pass runs,
what it made counts as changed in turn (``_changed``), which is how a new direction
reaches the composite. Left out on purpose: lights that cannot contribute (zero intensity, facing no
pixel, or an upper bound below ``skip_threshold`` of the scene's diffuse level), soft filtering where
sigma ~ 0 (soft = hard visibility) and whenever the soft visibility is not shown, shadow maps when no
shadows are shown, and the specular code on a scene without specular reflectance.
"""

from __future__ import annotations

import math
import time

import moderngl
import numpy as np

from ..backdrop import blurred_map
from ..errors import InputError
from ..ground import ground_plane
from ..lighting.lights import AreaLights
from ..scene import Scene
from ..lighting.median_cut import LUMINANCE
from ..settings import AUTO, EXPOSURE_LIMIT, VIEWS, VISIBILITY_MODES, Look
from .. import shadow_space as ss
from .composite_pass import CompositePass
from .context import make_current
from .display_pass import INSPECT_VIEWS, InspectPass
from .ground_pass import GroundShadowPass
from .kit import PassKit
from .light import PASS_HARD, PASS_OFF, PASS_SOFT, PASS_UNSHADOWED, Light, needed_pass, update_activity
from .light_pass import LIGHTS_PER_PASS, LightAtlas, LightShadingPass, RefinedVisibility
from .options import EngineOptions
from .outputs import EngineOutputs, in_context
from .picture import FramePicture, ImagePicture, PictureInputs
from .programs import shared_programs
from .scene_resources import SceneResources
from .shadow_passes import CsmBasisPass, PrefilterPass, ShadowMapPass

SHADING_VIEWS = ("diffuse_shading", "specular_shading")  # one term of the composite, shown alone

__all__ = ["Engine", "EngineOptions", "VIEWS", "LIGHTS_PER_PASS"]
DISPLAY_FIELDS = ("yaw", "tilt", "exposure", "tonemap", "background", "background_color", "compare")
BACKGROUND_FIELDS = ("yaw", "tilt", "background", "background_color")  # what the frame background shows


class Engine(EngineOutputs):
    """Owns the GL resources of one scene; ``set_lights`` and ``set_look``, then ``render``; read outputs back."""

    def __init__(self, ctx: moderngl.Context, scene: Scene, options: EngineOptions | None = None):
        self.ctx = ctx
        make_current(ctx)
        self.scene = scene
        o = self.options = options or EngineOptions()
        max_size = self._max_texture = int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
        if max(scene.width, scene.height, o.shadow_resolution, *scene.output_size) > max_size:
            raise InputError(scene.source, f"image {scene.width}x{scene.height} (output {scene.output_size[0]}x{scene.output_size[1]}) "
                             f"or shadow map {o.shadow_resolution} exceeds this GL's texture limit {max_size}")
        kit = self.kit = PassKit(ctx, shared_programs(ctx), o.profile)  # programs: once per context
        res = self.resources = SceneResources(kit, scene, o.shadow_step)
        self.shadow_step = res.shadow_step
        self._lights: list[Light] = []
        self._environment, self._uploaded_sigma = None, None  # the map as given; the backdrop blur it was uploaded with
        # the engine's first look: no background until one is set
        self.look = Look(background="color", background_color=(0.0, 0.0, 0.0))
        self._specular = scene.has_specular or not o.leave_out
        # the passes, in the order they run
        self.shadow_map_pass = ShadowMapPass(kit, res, o.shadow_resolution)
        self.csm_basis_pass = CsmBasisPass(kit, o.shadow_resolution, o.terms, o.prefilter)
        self.prefilter_pass = PrefilterPass(kit, o.shadow_resolution, o.terms)
        self.atlas = LightAtlas(kit, res.mask_box, max_size, scene.source)
        self.refined = RefinedVisibility(kit, res.mask_box)
        self.light_pass = LightShadingPass(kit, res, self.atlas, o.shadow_resolution, o.terms, self._specular, o.soft,
                                           o.pcss_min_texels)
        self.composite_pass = CompositePass(kit, res, (scene.width, scene.height), frame_shading=scene.frame is not None)
        self.inspect_pass = InspectPass(kit, res, (scene.width, scene.height))
        self.ground_pass = GroundShadowPass(kit, res, self.light_pass, scene.camera, ground_plane(scene), o.ground_scale)
        ground = self.ground_pass.texture
        self.picture = (ImagePicture(kit, res, (scene.width, scene.height), scene.camera, ground) if scene.frame is None
                        else FramePicture(kit, scene.frame, scene.camera, ground))
        self._light_passes = (self.shadow_map_pass, self.csm_basis_pass, self.prefilter_pass, self.light_pass)
        self._frame_passes = [self.composite_pass, self.ground_pass, *self.picture.passes]
        self._stale = {p.name: "all" for p in self._frame_passes}  # None, "box" (the mask's / matte's) or "all"
        self.complete = False  # the display holds a frame of the current state (render)
        self.composited = False  # ... or everything but the display is done (render(display=False))

    # ------------------------------------------------------------------ change tracking
    def _changed(self, what: str, lights=()):
        """``what`` changed (an input, or the output of a pass that ran): the passes that read it
        are stale: per-light passes for ``lights``, frame passes over their box or as a whole."""
        for p in self._light_passes:
            if what in p.inputs:
                for l in lights:
                    l.stale.add(p.name)
        for p in self._frame_passes:
            if what in getattr(p, "whole_inputs", ()):
                self._stale[p.name] = "all"
            elif what in p.inputs:
                self._stale[p.name] = self._stale[p.name] or "box"

    @property
    def counters(self):
        """Passes run so far, by name."""
        return self.kit.counters

    @property
    def timings(self) -> dict:
        return self.kit.timings

    @property
    def profile(self) -> bool:
        return self.kit.profile

    @profile.setter
    def profile(self, value: bool):
        self.kit.profile = bool(value)  # finishing GL work around every pass: for measuring only

    @property
    def programs(self):
        return self.kit.programs

    # ------------------------------------------------------------------ inputs
    @property
    def lights(self) -> AreaLights:
        return AreaLights(
            np.array([l.direction for l in self._lights]).reshape(-1, 3),
            np.array([l.sigma for l in self._lights]),
            np.array([l.intensity for l in self._lights]).reshape(-1, 3),
        )

    @in_context
    def set_lights(self, lights: AreaLights):
        """Replace the light set; only what changed is marked for recomputation."""
        lights.validate()
        if len(lights) != len(self._lights):
            for l in self._lights:
                l.release()
            self._lights = [Light(d.copy(), float(s), i.copy()) for d, s, i in zip(lights.direction, lights.sigma, lights.intensity)]
            self.atlas.allocate(self._lights)
            self._drop_refined()
            moved = list(range(len(self._lights)))
            self._changed("light_pass")
            if self.look.view == "shadow" and self.look.light >= len(self._lights):
                self._set_look(self.look.replace(view="final", light=0))  # the inspected light is gone
        else:
            moved = []
            turned = (np.array([l.direction for l in self._lights]) != lights.direction).any(axis=1)
            widened = np.array([l.sigma for l in self._lights]) != lights.sigma
            brightened = (np.array([l.intensity for l in self._lights]) != lights.intensity).any(axis=1)
            for k in np.flatnonzero(turned | widened | brightened):  # a drag turns every light: compared at once
                l = self._lights[k]
                if turned[k]:
                    l.direction = lights.direction[k].copy()
                    self._changed("direction", [l])
                    moved.append(int(k))
                if widened[k]:
                    l.sigma = float(lights.sigma[k])
                    self._changed("sigma", [l])
                    self._drop_refined()
                if brightened[k]:
                    l.intensity = lights.intensity[k].copy()
                    self._changed("intensity")
        if moved:
            self._drop_refined()
            res = self.resources
            dirs = np.array([self._lights[k].direction for k in moved])
            frames = ss.light_frames(res.caster_points, dirs, self.options.shadow_resolution, self.options.terms, sphere=res.sphere)
            facing = res.facing(dirs)
            for k, frame, f in zip(moved, frames, facing):
                self._lights[k].frame = frame
                self._lights[k].facing = max(float(f), 0.0)
        self._update_activity()

    def _update_activity(self):
        o, res = self.options, self.resources
        if update_activity(self._lights, res.response_bound, res.diffuse_bound, o.leave_out, o.skip_threshold):
            self._changed("activity")

    def set_look(self, look: Look):
        """What the user sees (:class:`viewer.settings.Look`, validated there): the display settings,
        the shadow mode, the terms and the view. The lights' rotation and intensity are the caller's
        (``set_lights``); here yaw and tilt turn the environment background."""
        if look.background == "photo" and self.scene.background is None and self.scene.frame is None:
            raise InputError(None, "this scene bundle has no background image (background.png)")
        if look.view == "shadow" and not look.light < len(self._lights):
            raise InputError(None, f"no light {look.light}: there are {len(self._lights)}")
        self._set_look(look)

    @property
    def feet(self) -> bool:
        """Whether the person's feet are in the frame (viewer.ground)."""
        return self.ground_pass.plane.feet

    @property
    def ground_shown(self) -> bool:
        """Whether the look shows the ground shadow (``Look.ground``, "auto" resolved for this scene)."""
        return self.look.ground_shown(self.feet, self.look.background)

    @property
    def shown_look(self) -> Look:
        """The look as the display draws it: its ground "auto" resolved (:attr:`ground_shown`); a
        shading view (albedo 1, or the specular term alone) exposed so that every active light at
        once, head-on, is white: under the photo's exposure, made for albedos of a few tenths, it
        would clip to white."""
        look = self.look.replace(ground=self.ground_shown)
        if look.view in SHADING_VIEWS:
            peak = sum(float(l.intensity @ LUMINANCE) for l in self._lights if l.active)
            stops = -math.log2(peak) if peak > 0.0 and math.isfinite(peak) else 0.0
            look = look.replace(exposure=float(np.clip(stops, -EXPOSURE_LIMIT, EXPOSURE_LIMIT)))
        return look

    def _set_look(self, look: Look):
        old, terms, shown = self.look, self._composite_terms(), self.ground_shown
        self.look = look
        if self._environment is not None and self.backdrop_sigma != self._uploaded_sigma:
            self._upload_environment()
        if self.ground_shown != shown:
            self._changed("ground")
        if look.shadows != old.shadows:
            self._changed("visibility")  # lights whose light pass lacks what the mode needs redo it in render()
        if self._composite_terms() != terms:
            self._changed("terms")
        if (look.view, look.light if look.view == "shadow" else 0) != (old.view, old.light if old.view == "shadow" else 0):
            self._changed("view")
        if any(not np.array_equal(getattr(look, f), getattr(old, f)) for f in DISPLAY_FIELDS):
            self._changed("display")
        if any(not np.array_equal(getattr(look, f), getattr(old, f)) for f in BACKGROUND_FIELDS):
            self._changed("background")

    def set_visibility(self, mode: str):
        """Which visibility the composite uses: 'soft' (EngineOptions.soft), 'hard' (shadow map), 'none', or
        'refined' (the refinement network's, see ``set_refined_visibility``; soft until it is set)."""
        if mode not in VISIBILITY_MODES:
            raise ValueError(f"visibility must be one of {', '.join(VISIBILITY_MODES)}, got {mode!r}")
        self.set_look(self.look.replace(shadows=mode))

    def set_view(self, view: str = "final", light: int = 0):
        """What the display image shows (``VIEWS``): the relit frame; the diffuse or specular shading
        alone; the albedo, normal, depth, specular or roughness map; or light ``light``'s shadow
        (its visibility under the current shadow mode, soft when no shadows are shown). Checked
        where every look is: ``Look`` (the view) and ``set_look`` (the light's index)."""
        self.set_look(self.look.replace(view=view, light=int(light) if view == "shadow" else self.look.light))

    def _drop_refined(self):
        """The lights' shadows changed: the refined visibility no longer applies (the composite
        uses the soft visibility until ``set_refined_visibility`` is called again)."""
        if self.refined.current:
            self.refined.current = False
            if self.look.shadows == "refined":
                self._changed("refined_visibility")

    @property
    def refined_current(self) -> bool:
        """Whether the refined visibility of the current lights has been set."""
        return self.refined.current

    @in_context
    def set_refined_visibility(self, visibility: np.ndarray):
        """The shadow refinement network's visibility (N, H, W) of the current lights, shown in the
        'refined' mode until a light's direction or sigma changes (then the soft visibility is
        shown until it is set again). Values are clipped to [0, 1]; non-finite values refused."""
        vis = np.asarray(visibility, np.float32)
        h, w = self.scene.height, self.scene.width
        if vis.shape != (len(self._lights), h, w):
            raise ValueError(f"refined visibility must be ({len(self._lights)}, {h}, {w}), got {vis.shape}")
        if not np.all(np.isfinite(vis)):
            raise ValueError("refined visibility has NaN or Inf values")
        self.refined.write(self._lights, vis, self.atlas.planes[0].size)
        if self.look.shadows == "refined":
            self._changed("refined_visibility")

    def _composite_terms(self) -> tuple[float, float, bool]:
        """(diffuse weight, specular weight, unit albedo) of the composite: the shading views show
        one term; every other view keeps the relit image (the HDR output) as the switches say."""
        view = self.look.view
        if view == "diffuse_shading":
            return 1.0, 0.0, True
        if view == "specular_shading":
            return 0.0, 1.0, False
        return float(self.look.diffuse), float(self.look.specular), False

    @in_context
    def set_environment(self, pixels: np.ndarray):
        """Upload an equirectangular map (H, W, 3) linear RGB for the 'environment' background
        (blurred by the look's backdrop blur)."""
        self._environment = np.asarray(pixels, dtype=np.float32)
        self._upload_environment()

    @property
    def backdrop_sigma(self) -> float:
        """The backdrop's blur (radians): the look's, or ("auto") the photo's own background defocus."""
        blur = self.look.backdrop_blur
        if blur == AUTO:
            return self.scene.frame.background_blur if self.scene.frame is not None else 0.0
        return float(np.radians(blur))

    def _upload_environment(self):
        if self._environment is None:
            return
        sigma = self.backdrop_sigma
        self.resources.set_environment(blurred_map(self._environment, sigma))
        self._uploaded_sigma = sigma
        self._changed("environment")

    # ------------------------------------------------------------------ scheduling
    def _needed_pass(self, l: Light) -> int:
        """The light-pass mode the current visibility and view need for this light (light.needed_pass)."""
        inspected = self._lights[self.look.light] if self.look.view == "shadow" else None
        return needed_pass(l, self.look.shadows, inspected, self._soft_is_hard(l))

    def _soft_is_hard(self, l: Light) -> bool:
        """sigma ~ 0: the light's soft visibility is its hard one and its filtering is skipped."""
        return self.options.leave_out and l.sigma < self.options.hard_sigma

    @in_context
    def render(self, budget: float | None = None, display: bool = True) -> "Engine":
        """Bring every output up to date, redoing only the passes whose inputs changed. Each stage
        runs for all lights before the next starts: llvmpipe waits once per stage, not per pass.

        ``budget`` (seconds): stop once that much time has gone, between one light's or one group's
        work and the next (one unit of work at least), leaving the rest stale for the next call; the
        display is drawn only when everything before it is done, so it keeps the last complete frame
        meanwhile (a window opening a map or a photo stays live, :attr:`complete` says when the new
        frame is there). ``display`` False stops before the display (:attr:`composited` says all the
        rest is done: the HDR can be read and an exposure chosen from it before the frame is drawn)."""
        if not self._lights:
            raise ValueError("no lights: call set_lights first")
        start, units = time.perf_counter(), [0]

        def spent() -> bool:
            """Before a unit of work: whether the budget is spent (never before the first unit)."""
            if budget is not None and units[0] > 0:
                self.ctx.finish()  # llvmpipe works at the flush: the time is the work's only once it is done
                if time.perf_counter() - start > budget:
                    return True
            units[0] += 1
            return False

        self.complete = self.composited = False
        active = [l for l in self._lights if l.active]  # inactive lights stay stale until they count
        need = {id(l): self._needed_pass(l) for l in self._lights}
        if self.look.shadows == "none":  # the composite ignores visibility: any computed pass will do
            for l in self._lights:
                if need[id(l)] == PASS_UNSHADOWED and l.pass_mode != PASS_OFF and "light_pass" not in l.stale:
                    need[id(l)] = l.pass_mode
        for l in active:
            if "shadow_map" in l.stale and need[id(l)] in (PASS_HARD, PASS_SOFT):
                if spent():
                    return self
                self.shadow_map_pass.run(l)
                self._ran(self.shadow_map_pass, [l])
        # CSM's basis and pre-filter; contact-hardening soft shadows read the shadow map itself
        to_filter = [l for l in active if "csm_basis" in l.stale and need[id(l)] == PASS_SOFT and self.options.soft == "csm"]
        for l in to_filter:
            self.csm_basis_pass.run(l)
        self._ran(self.csm_basis_pass, to_filter)
        for axis in ((1, 0), (0, 1)):
            for l in to_filter:
                self.prefilter_pass.run_axis(l, axis)
        self._ran(self.prefilter_pass, to_filter)
        for g in range(0, len(self._lights), LIGHTS_PER_PASS):
            group = self._lights[g:g + LIGHTS_PER_PASS]
            if any(l.active and ("light_pass" in l.stale or l.pass_mode != need[id(l)]) for l in group):
                if spent():
                    return self
                # the whole group is redone; a skipped light's slot is zeroed, so it is redone when it counts again
                self.light_pass.run(group, [need[id(l)] for l in group])
                for l in group:
                    l.pass_mode = need[id(l)]
                    if not l.active:
                        l.stale.add(self.light_pass.name)
                self._ran(self.light_pass, [l for l in group if l.active])
        if self._stale["composite"]:
            if spent():
                return self
            self.composite_pass.run(self._lights, self.atlas, self.refined, self.look.shadows, self._composite_terms())
            self._ran(self.composite_pass)
        if self.ground_shown and self._stale["ground_shadow"]:  # left out (and stale) while not shown
            if spent():
                return self
            self.ground_pass.run(self._lights, self.look.shadows)
            self._ran(self.ground_pass)
        self.composited = True
        last = self.picture.last.name
        if self._stale[last]:
            if not display or spent():
                return self
            self._draw_picture(whole=self._stale[last] == "all")
            self._stale[last] = None
        self.complete = True
        return self

    def _ran(self, p, lights=()):
        """Pass ``p`` brought its result up to date (for ``lights``): its output changed."""
        for l in lights:
            l.stale.discard(p.name)
        if p.name in self._stale:
            self._stale[p.name] = None
        self._changed(p.name, lights)

    def _draw_picture(self, whole: bool):
        look = self.shown_look
        if look.view in INSPECT_VIEWS:  # an inspection view draws into the picture's place
            light = self._lights[look.light] if look.view == "shadow" else None
            self.inspect_pass.run(self.picture.last.fbo, look.view, light, self.atlas, look.shadows)
        else:
            self.picture.draw(self._picture_inputs(look), whole)

    def _picture_inputs(self, shown: Look | None = None) -> PictureInputs:
        """What the picture draws and reads from, now (``shown``: the shown look, when the caller has it)."""
        return PictureInputs(self.composite_pass, shown or self.shown_look, self.look.background, self._composite_terms(),
                             self.resources.environment, lambda name: bool(self._stale[name]), self._ran)

    def light_active(self, index: int) -> bool:
        return self._lights[index].active

    @in_context
    def release(self):
        """Free every GL object the engine created (the context and its programs stay)."""
        for l in self._lights:
            l.release()
        self._lights = []
        for owner in (self.atlas, self.refined, self.picture, self.composite_pass,
                      self.ground_pass, self.shadow_map_pass, self.resources, self.kit):
            if owner is not None:
                owner.release()
