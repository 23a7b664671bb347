"""The GL engine: renders a scene bundle under a set of area lights, redoing only what changed.

The engine only orders the passes and tracks what changed; each pass is an object that owns its GL
resources and names, in ``inputs``, what makes its result stale. The passes, their order and their
inputs are written in one place, docs/engine.md's cache table, which ``tests/test_engine.py`` holds
to these declarations.

Reading results back is the other half of the interface (``output``, outputs.py); the final
picture, an image or a photo's frame, is one object with one interface (picture.py); the look and
the map behind are look_state.py's; what is stale is staleness.py's: when a pass runs, what it made
counts as changed in turn, which is how a new direction reaches the composite. Left out on purpose:
lights that cannot contribute (zero intensity, facing no pixel, or an upper bound below
``skip_threshold`` of the scene's diffuse level), soft filtering where sigma ~ 0 (soft = hard
visibility) and whenever the soft visibility is not shown, shadow maps when no shadows are shown,
and the specular code on a scene without specular reflectance.
"""

from __future__ import annotations

import moderngl
import numpy as np

from viewer.errors import InputError
from viewer.gl.composite_pass import CompositePass
from viewer.gl.context import make_current
from viewer.gl.display_pass import INSPECT_VIEWS, InspectPass
from viewer.gl.ground_pass import GroundShadowPass
from viewer.gl.kit import PassKit
from viewer.gl.light import PASS_HARD, PASS_OFF, PASS_SOFT, PASS_UNSHADOWED, Light, frame_lights, needed_pass, update_activity
from viewer.gl.light_pass import LIGHTS_PER_PASS, LightAtlas, LightShadingPass, RefinedVisibility
from viewer.gl.look_state import LookState
from viewer.gl.options import EngineOptions
from viewer.gl.outputs import Readback, in_context
from viewer.gl.picture import FramePicture, ImagePicture, PictureInputs
from viewer.gl.programs import shared_programs
from viewer.gl.scene_resources import SceneResources
from viewer.gl.shadow_passes import CsmBasisPass, PrefilterPass, ShadowMapPass
from viewer.gl.staleness import Staleness
from viewer.gl.work_budget import WorkBudget
from viewer.scene.area_lights import AreaLights
from viewer.scene.bundle import Scene
from viewer.scene.ground import ground_plane
from viewer.scene.look import VIEWS, VISIBILITY_MODES, Look

__all__ = ["Engine", "EngineOptions", "VIEWS", "LIGHTS_PER_PASS"]


class Engine:
    """Owns the GL resources of one scene; ``set_lights`` and ``set_look``, then ``render``; read
    outputs back through ``output`` (:class:`viewer.gl.outputs.Readback`)."""

    def __init__(self, ctx: moderngl.Context, scene: Scene, options: EngineOptions | None = None, background_camera=None):
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
        self._given: tuple[AreaLights, AreaLights | None] | None = None  # set_lights' map and placed lights
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
        self.looks = LookState(scene, res, self.ground_pass.plane.feet)
        ground = self.ground_pass.texture
        self.picture = (ImagePicture(kit, res, (scene.width, scene.height), scene.camera, ground) if scene.frame is None
                        else FramePicture(kit, scene.frame, scene.camera, ground, background_camera))
        self.stale = Staleness((self.shadow_map_pass, self.csm_basis_pass, self.prefilter_pass, self.light_pass),
                               (self.composite_pass, self.ground_pass, *self.picture.passes))
        self.output = Readback(kit, self.picture, self.composite_pass, self.ground_pass, self.atlas, res, self.csm_basis_pass,
                               lambda: self._lights, self._picture_inputs, self._soft_is_hard)
        self._unit_costs: dict[str, float] = {}  # seconds each kind of unit of work took last (WorkBudget)
        self._partial = {"ground": -1, "picture": -1}  # Staleness.changes when a budgeted render left each part-way
        self.complete = False  # the display holds a frame of the current state (render)
        self.composited = False  # ... or everything but the display is done (render(display=False))

    @property
    def display(self) -> moderngl.Texture:
        """The display image shown and saved: at the output frame's resolution for a scene with a
        frame layer (the inspection views too), else at the maps'."""
        return self.picture.last.image

    @property
    def output_size(self) -> tuple[int, int]:
        """(width, height) of :attr:`display` and of the HDR read back."""
        return self.display.size

    @property
    def lights(self) -> AreaLights:
        ls = self._lights
        return AreaLights(np.array([l.direction for l in ls]).reshape(-1, 3), np.array([l.sigma for l in ls]),
                          np.array([l.intensity for l in ls]).reshape(-1, 3))

    @in_context
    def set_lights(self, lights: AreaLights, placed: AreaLights | None = None):
        """The map's lights as fitted, which the look turns (yaw, tilt) and scales (intensity) with the
        map behind, and ``placed`` lights fixed to the camera; only what changed is redone."""
        self._given = (lights.validate(), placed if placed is None else placed.validate())
        self._set_turned(self.looks.turned(lights, placed).validate())  # together within MAX_LIGHTS too

    def _set_turned(self, lights: AreaLights):
        if len(lights) != len(self._lights):
            for l in self._lights:
                l.release()
            self._lights = [Light(d.copy(), float(s), i.copy()) for d, s, i in zip(lights.direction, lights.sigma, lights.intensity)]
            self.atlas.allocate(self._lights)
            self._drop_refined()
            moved = list(range(len(self._lights)))
            self.stale.changed("light_pass")
            if self.look.view == "shadow" and self.look.light >= len(self._lights):
                self._apply_look(self.look.replace(view="final", light=0))  # the inspected light is gone
        else:
            moved = []
            turned = (np.array([l.direction for l in self._lights]) != lights.direction).any(axis=1)
            widened = np.array([l.sigma for l in self._lights]) != lights.sigma
            brightened = (np.array([l.intensity for l in self._lights]) != lights.intensity).any(axis=1)
            for k in np.flatnonzero(turned | widened | brightened):  # a drag turns every light: compared at once
                l = self._lights[k]
                if turned[k]:
                    l.direction = lights.direction[k].copy()
                    self.stale.changed("direction", [l])
                    moved.append(int(k))
                if widened[k]:
                    l.sigma = float(lights.sigma[k])
                    self.stale.changed("sigma", [l])
                    self._drop_refined()
                if brightened[k]:
                    l.intensity = lights.intensity[k].copy()
                    self.stale.changed("intensity")
        if moved:
            self._drop_refined()
            frame_lights([self._lights[k] for k in moved], self.resources, self.options.shadow_resolution, self.options.terms)
        o, res = self.options, self.resources
        if update_activity(self._lights, res.response_bound, res.diffuse_bound, o.leave_out, o.skip_threshold):
            self.stale.changed("activity")

    def set_look(self, look: Look):
        """What the user sees (:class:`viewer.scene.look.Look`, validated there), all of it: yaw and
        tilt turn the map's lights and the map behind together, the intensities scale the lights,
        the background falls back to what the scene has (:meth:`LookState.resolved`), and the
        display settings, shadow mode, terms and view follow."""
        self.looks.check(look, len(self._lights))
        turns = self.looks.turns(look)
        self._apply_look(look)
        if turns and self._given is not None:
            self._set_turned(self.looks.turned(*self._given).validate())

    def _apply_look(self, look: Look):
        for what in self.looks.replace(look):
            self.stale.changed(what)

    @property
    def look(self) -> Look:
        return self.looks.look

    @property
    def feet(self) -> bool:
        """Whether the person's feet are in the frame (viewer.scene.ground)."""
        return self.looks.feet

    @property
    def ground_shown(self) -> bool:
        return self.looks.ground_shown

    @property
    def shown_look(self) -> Look:
        """The look as the display draws it (:meth:`LookState.shown`)."""
        return self.looks.shown([l.intensity for l in self._lights if l.active])

    @in_context
    def set_environment(self, pixels: np.ndarray | None):
        """Upload an equirectangular map (H, W, 3) linear RGB for the 'environment' background
        (blurred by the look's backdrop blur); None: no map behind (the look's background falls back)."""
        for what in self.looks.set_environment(pixels):
            self.stale.changed(what)

    def set_visibility(self, mode: str):
        """Which visibility the composite uses: 'soft' (EngineOptions.soft), 'hard' (shadow map), 'none', or
        'refined' (the refinement network's, see ``set_refined_visibility``; soft until it is set)."""
        if mode not in VISIBILITY_MODES:
            raise ValueError(f"visibility must be one of {', '.join(VISIBILITY_MODES)}, got {mode!r}")
        self.set_look(self.looks.asked.replace(shadows=mode))

    def set_view(self, view: str = "final", light: int = 0):
        """What the display image shows (``VIEWS``): the relit frame; the diffuse or specular shading
        alone; the albedo, normal, depth, specular or roughness map; or light ``light``'s shadow
        (its visibility under the current shadow mode, soft when no shadows are shown). Checked
        where every look is: ``Look`` (the view) and ``set_look`` (the light's index)."""
        self.set_look(self.looks.asked.replace(view=view, light=int(light) if view == "shadow" else self.looks.asked.light))

    def _drop_refined(self):
        """The lights' shadows changed: the refined visibility no longer applies (the composite
        uses the soft visibility until ``set_refined_visibility`` is called again)."""
        if self.refined.current and self.look.shadows == "refined":
            self.stale.changed("refined_visibility")
        self.refined.current = False

    @property
    def refined_current(self) -> bool:
        """Whether the refined visibility of the current lights has been set."""
        return self.refined.current

    @in_context
    def set_refined_visibility(self, visibility: np.ndarray):
        """The shadow refinement network's visibility (N, H, W) of the current lights, shown in the
        'refined' mode until a light's direction or sigma changes (then the soft visibility is
        shown until it is set again). Values are clipped to [0, 1]; non-finite values refused."""
        self.refined.set(self._lights, visibility, (self.scene.height, self.scene.width), self.atlas.planes[0].size)
        if self.look.shadows == "refined":
            self.stale.changed("refined_visibility")

    # ------------------------------------------------------------------ scheduling
    def _needed_pass(self, l: Light, soft_planes: bool = False) -> int:
        """The light-pass mode the current visibility and view need for this light (light.needed_pass);
        ``soft_planes``: its soft visibility too, whatever is shown."""
        inspected = self._lights[self.look.light] if self.look.view == "shadow" else None
        shown = "soft" if soft_planes and self.look.shadows in ("hard", "none") else self.look.shadows
        return needed_pass(l, shown, inspected, self._soft_is_hard(l))

    def _soft_is_hard(self, l: Light) -> bool:
        """sigma ~ 0: the light's soft visibility is its hard one and its filtering is skipped."""
        return self.options.leave_out and l.sigma < self.options.hard_sigma

    @in_context
    def render(self, budget: float | None = None, display: bool = True, soft_planes: bool = False) -> Engine:
        """Bring every output up to date, redoing only the passes whose inputs changed. Each stage
        runs for all lights before the next starts: llvmpipe waits once per stage, not per pass.

        ``budget`` (seconds): stop once that much time has gone, between one unit of work and the
        next (a light's shadow map, a band of a group's light pass...; one unit at least), leaving the rest stale for the next call; the
        display is drawn only when everything before it is done, so it keeps the last complete frame
        meanwhile (a window opening a map or a photo stays live, :attr:`complete` says when the new
        frame is there). ``display`` False stops before the display (:attr:`composited` says all the
        rest is done: the HDR can be read and an exposure chosen from it before the frame is drawn).
        ``soft_planes``: every active light's planes hold its soft visibility too, whatever shadows
        are shown (the passes sheet reads both; the picture is the same)."""
        if not self._lights:
            raise ValueError("no lights: call set_lights first")
        work = WorkBudget(self.ctx, budget, self._unit_costs)
        in_units = work if budget is not None else None  # what the ground and the picture get: None, all at once
        self.complete = self.composited = False
        active = [l for l in self._lights if l.active]  # inactive lights stay stale until they count
        need = {id(l): self._needed_pass(l, soft_planes) for l in self._lights}
        if self.look.shadows == "none":  # the composite ignores visibility: any computed pass will do
            for l in self._lights:
                if need[id(l)] == PASS_UNSHADOWED and l.pass_mode != PASS_OFF and "light_pass" not in l.stale:
                    need[id(l)] = l.pass_mode
        for l in active:
            if "shadow_map" in l.stale and need[id(l)] in (PASS_HARD, PASS_SOFT):
                if work.spent("shadow_map"):
                    return self
                self.shadow_map_pass.run(l)
                self.stale.ran(self.shadow_map_pass, [l])
        # the CSM's basis and pre-filter, for a soft-shadow method that reads them (contact-hardening reads the shadow map)
        to_filter = [l for l in active if "csm_basis" in l.stale and need[id(l)] == PASS_SOFT and self.light_pass.soft.prefiltered]
        if to_filter:
            for l in to_filter:
                self.csm_basis_pass.run(l)
            self.stale.ran(self.csm_basis_pass, to_filter)
            for axis in ((1, 0), (0, 1)):
                for l in to_filter:
                    self.prefilter_pass.run_axis(l, axis)
            self.stale.ran(self.prefilter_pass, to_filter)
        for g in range(0, len(self._lights), LIGHTS_PER_PASS):
            group = self._lights[g:g + LIGHTS_PER_PASS]
            if any(l.active and ("light_pass" in l.stale or l.pass_mode != need[id(l)]) for l in group):
                # the whole group is redone; a skipped light's slot is zeroed, so it is redone when it counts again
                if work.spent("light_pass") or not self.light_pass.run(group, [need[id(l)] for l in group], in_units):
                    return self  # its bands go on at the next call while its lights stay as they are
                for l in group:
                    l.pass_mode = need[id(l)]
                    if not l.active:
                        l.stale.add(self.light_pass.name)
                self.stale.ran(self.light_pass, [l for l in group if l.active])
        if self.stale.frame["composite"]:
            if work.spent("composite"):
                return self
            self.composite_pass.run(self._lights, self.atlas, self.refined, self.look.shadows, self.looks.composite_terms())
            self.stale.ran(self.composite_pass)
        if self.looks.ground_shown and self.stale.frame["ground_shadow"]:  # left out (and stale) while not shown
            if self.stale.changes != self._partial["ground"]:  # anything changed since its groups were left part-way
                self.ground_pass.restart()
            if work.spent("ground_shadow") or not self.ground_pass.run(self._lights, self.look.shadows, in_units):
                self._partial["ground"] = self.stale.changes
                return self
            self.stale.ran(self.ground_pass)
        self.composited = True
        last = self.picture.last.name
        if self.stale.frame[last]:
            if not display:
                work.close()
                return self
            if self.stale.changes != self._partial["picture"]:  # anything changed since its bands were left part-way
                self.picture.restart()
            if not self._draw_picture(self.stale.frame[last] == "all", in_units):
                self._partial["picture"] = self.stale.changes
                return self
            self.stale.frame[last] = None
        work.close()
        self.complete = True
        return self

    def _draw_picture(self, whole: bool, work: WorkBudget | None) -> bool:
        """Draw the picture; with ``work`` (a budgeted render) in units, False when it ran out first."""
        look = self.shown_look
        if look.view in INSPECT_VIEWS:  # an inspection view draws into the picture's place
            if work is not None and work.spent("inspect"):
                return False
            light = self._lights[look.light] if look.view == "shadow" else None
            self.inspect_pass.run(self.picture.last.fbo, look.view, light, self.atlas, look.shadows)
            return True
        return self.picture.draw(self._picture_inputs(look), whole, work)

    def _picture_inputs(self, shown: Look | None = None) -> PictureInputs:
        """What the picture draws and reads from, now (``shown``: the shown look, when the caller has it)."""
        return PictureInputs(self.composite_pass, shown or self.shown_look, self.look.background, self.looks.composite_terms(),
                             self.resources.environment, lambda name: bool(self.stale.frame[name]), self.stale.ran)

    def light_active(self, index: int) -> bool:
        return self._lights[index].active

    @in_context
    def release(self):
        """Free every GL object the engine created (the context and its programs stay)."""
        if self.kit.ctx.screen is not None:  # none of its framebuffers stays bound (PassKit.scratch_target)
            self.kit.ctx.screen.use()
        for l in self._lights:
            l.release()
        self._lights = []
        for owner in (self.atlas, self.refined, self.picture, self.composite_pass, self.light_pass,
                      self.ground_pass, self.shadow_map_pass, self.resources, self.kit):
            if owner is not None:
                owner.release()
