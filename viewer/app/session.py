"""The relighting session behind the window: one scene, its lights, the engines, one context.

The *final* engine renders at the bundle's resolution with the chosen options; the *preview*
engines (:mod:`viewer.app.preview`) render the same scene resampled to a coarser level, with hard
shadows in place of soft ones (filtering the soft shadows of 16 lights costs more than everything
else at that size), and are used only while the lighting is being dragged, so a drag stays
interactive: the window's pace picks the level from the dragged frames' times
(:attr:`Session.preview_level`). When the drag stops a preview engine's full-quality frame of the
same state shows first (:meth:`Session.render_coarse`), then the final engine's, so what stays on
screen is always the full-quality frame of the current state. Each frame shown is one complete
engine render of one state: never a mix of old and new lights.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from viewer.app.preview import START_LEVEL, PreviewEngines
from viewer.app.refined_shadows import RefinedShadows
from viewer.gl import Engine, EngineOptions
from viewer.lighting.placed_lights import History, PlacedLight, level, rescaled, to_area_lights
from viewer.scene.area_lights import AreaLights
from viewer.scene.bundle import Scene
from viewer.scene.look import Look

SHADOW_MODES = {"soft (area lights)": "soft", "refined (network)": "refined", "shadow map (hard)": "hard", "none": "none"}
BACKGROUND_NAMES = {"map": "environment", "photo": "photo", "grey": "color"}  # what the panel offers behind the person
VIEW_NAMES = {
    "final": "relit image", "diffuse_shading": "diffuse shading", "specular_shading": "specular shading",
    "albedo": "albedo", "normal": "normal", "depth": "depth", "specular": "specular", "roughness": "roughness",
    "shadow": "shadow of the selected light",
}


class Session:
    def __init__(self, ctx, scene: Scene, lights: AreaLights, environment: np.ndarray | None,
                 options: EngineOptions | None = None, look: Look | None = None, background_camera=None):
        self.ctx = ctx
        self.scene = scene
        self.options = options or EngineOptions()
        self.environment = environment
        self.background_camera = background_camera  # the lens the map behind is seen through, when not the scene's (a clip's shot)
        # a clip's frame: (yaw, tilt) degrees its camera turned since its shot began; the map turns by as much
        # on top of the look's (viewer.output.clip_frames), so the new background moves as the old one did
        self.camera_turn = (0.0, 0.0)
        self.camera_height = 0.0  # metres: a clip shot's camera above the ground (ClipFrames.camera_height; 0: not read)
        # the final engine is to get the map in a render call of its own (set_scene): None, or "made"
        # (the engine was made since the last render call) or "next" (the next call gives it)
        self._map_pending: str | None = None
        self._make_engines()
        self.preview_level = START_LEVEL  # the drag preview's level (viewer.app.preview.PREVIEW_LEVELS; the window's pace sets it)
        self.outgoing: Engine | None = None  # the person before, shown until the new one's first frame is complete (set_scene)
        self.base_lights = lights
        self.sigma = lights.sigma.copy()  # the user's sigma per light (sliders)
        self.placed: tuple[PlacedLight, ...] = ()  # the user's own lights, fixed to the camera (viewer.lighting.placed_lights)
        self.history = History()
        self.keep_absolute = False  # placed lights keep their absolute intensities when the map changes
        self.look = (look or Look()).fitted(len(lights))
        self.wake = lambda: None  # called when background work finishes (the window's wake)
        self.refined = RefinedShadows(lambda: self.wake())

    # ------------------------------------------------------------------ state
    @property
    def map_lights(self) -> AreaLights:
        """The map's lights with the user's sigmas, as the engine takes them (the look turns and scales them)."""
        return AreaLights(self.base_lights.direction, self.sigma, self.base_lights.intensity)

    @property
    def lights(self) -> AreaLights:
        """The map's lights as rendered: the user's sigmas and the map's intensity, before the rotation."""
        return self.map_lights.scaled(self.look.intensity)

    @property
    def rendered_look(self) -> Look:
        """The look the engines render: the user's, its map turned on by a clip frame's :attr:`camera_turn`
        and seen from its :attr:`camera_height`."""
        return self.look.on_frame(self.camera_turn, self.camera_height)

    def rotated_lights(self) -> AreaLights:
        look = self.rendered_look
        return self.lights.rotated(look.yaw, look.tilt)

    def rendered_lights(self) -> AreaLights:
        """What the engines render (:meth:`Look.turned`): the map's lights turned and scaled by the
        look, then the placed lights (fixed to the camera) scaled by its placed intensity."""
        return self.rendered_look.turned(self.map_lights, to_area_lights(self.placed))

    def set_placed(self, placed, record: bool = True):
        """The user's lights (a rig, an added, moved or deleted light); ``record``: undo brings back
        the ones before."""
        placed = tuple(placed)
        if placed == self.placed:
            return
        if record:
            self.history.record(self.placed)
        self.placed = placed
        self.look = self.look.fitted(len(self.base_lights) + len(placed))

    def undo(self) -> bool:
        return self._placed_again(self.history.undo(self.placed))

    def redo(self) -> bool:
        return self._placed_again(self.history.redo(self.placed))

    def _placed_again(self, placed) -> bool:
        """The placed lights undo or redo brings back (None: none to bring), set without recording."""
        if placed is not None:
            self.set_placed(placed, record=False)
        return placed is not None

    def set_lights(self, lights: AreaLights, environment: np.ndarray | None = None, new_map: bool = False):
        """New lights (a refit, or another map with its pixels): the sliders start from their sigmas.
        ``new_map``: the placed lights keep their share of the light (scaled by the ratio of the
        maps' levels, undo and redo with them) unless ``keep_absolute``."""
        if new_map and not self.keep_absolute:
            factor = level(lights) / level(self.base_lights)
            self.placed = rescaled(self.placed, factor)
            self.history.rescale(factor)
        self.base_lights = lights
        self.sigma = lights.sigma.copy()
        if environment is not None:
            self.environment = environment
            self._map_pending = None
            self._set_environment(self.final)
            self.previews.set_environment(environment)
        self.look = self.look.fitted(len(lights) + len(self.placed))

    def set_scene(self, scene: Scene, background_camera=None):
        """Another person (a photo or bundle opened in the window, a clip's frame): new engines for it;
        the lights, placed lights and look stay (a scene without a photo has no before / after). The old
        final engine stays (:meth:`render` shows it) until the new one has a complete frame.
        ``background_camera``: the lens the map behind is seen through, when not the scene's own."""
        self.refined.forget()
        self.previews.release()
        if self.outgoing is not None:
            self.outgoing.release()
        self.outgoing = self.final
        self.scene = scene
        self.background_camera = background_camera
        self._make_engines(map_later=True)
        if scene.frame is None:
            self.look = replace(self.look, compare=0.0)

    def set_options(self, options: EngineOptions):
        """New engine options (a quality preset): the engines are made again; the next render
        brings them up to the current state."""
        if options == self.options:
            return
        self.release()
        self.refined.forget()  # a running refinement was for the old engine's shadow maps
        self.options = options
        self._make_engines()

    def set_sigma(self, index: int, sigma: float):
        self.sigma[index] = max(float(sigma), 0.0)

    def update(self, **changes):
        self.look = replace(self.look, **changes)

    @property
    def ground_shown(self) -> bool:
        """Whether the ground shadow shows (the look's "auto" resolved for this scene and background)."""
        background = self.final.looks.resolved(self.look).background
        if self._map_pending and self.look.background == "environment":
            background = "environment"  # the map is on its way to the new person's engine (render)
        return self.look.ground_shown(self.final.feet, background)

    def state_key(self) -> bytes:
        """What a frame shows, as bytes: the look, the map's lights and sigmas, the placed lights, the clip
        frame's camera turn and height."""
        return self.lighting_key() + repr((self.camera_turn, self.camera_height)).encode()

    def lighting_key(self) -> bytes:
        """:meth:`state_key` but the camera turn and height: what every frame of a clip is lit by alike."""
        return repr((self.look, self.placed)).encode() + self.sigma.tobytes() + self.base_lights.direction.tobytes()

    # ------------------------------------------------------------------ engines
    def _make_engines(self, map_later: bool = False):
        """The final engine and the preview's for the scene and options, given the map (``map_later``:
        by the render call after the next budgeted one, the window's next frame, not the frame that made
        the engine: a new person's engine is ~50-300 ms to make at 1-2.8 MP and the map's blur and upload
        ~40-50 ms more)."""
        self.final = Engine(self.ctx, self.scene, self.options, self.background_camera)
        self._map_pending = "made" if map_later and self.environment is not None else None
        if not self._map_pending:
            self._set_environment(self.final)
        self.previews = PreviewEngines(self.ctx, self.scene, self.options, self.background_camera)
        self.previews.set_environment(self.environment)

    @property
    def preview(self) -> Engine:
        """The drag preview's engine at the current level."""
        return self.previews.engine(self.preview_level)

    def warm_preview(self, budget: float | None = None) -> bool:
        """One step towards the preview engines the next drag may need (:meth:`PreviewEngines.warm`; a
        first frame drawn with ``budget`` seconds, as much of it as fits); False when there was none."""
        return self.previews.warm(self.preview_level, lambda eng: self._render_preview(eng, True, budget, True).complete)

    def render_coarse(self) -> Engine:
        """The full-quality frame at the preview's level (the look's soft shadows, refined ones as soft, and
        skin): what shows the moment the lighting stops, while the final engine draws the sharp one."""
        return self._render_preview(self.preview, False, None, True, full=True)

    def _set_environment(self, eng: Engine):
        if self.environment is not None:
            eng.set_environment(self.environment)

    def render(self, preview: bool = False, hard: bool = True, budget: float | None = None,
               display: bool = True) -> Engine:
        """Bring the chosen engine up to the current state and render it; returns the engine whose
        ``display`` texture is the frame to show: the one rendered, or with ``budget`` (seconds, the
        engine stops when it is spent and goes on at the next call) the last complete frame: the
        person before while a new one's first frame is not done. The preview shows hard shadows for
        soft and refined ones (the lighting dragged), or with ``hard`` False soft ones (a light's
        size or an intensity being changed: what the slider changes shows). ``display`` False: all
        but the display (``Engine.render``), the last complete frame still shown."""
        if preview:
            return self._render_preview(self.preview, hard, budget, display)
        eng = self.final
        if self._map_pending:  # "made": a budgeted call of a frame that made the engine does nothing more
            shown = self.outgoing if self.outgoing is not None else eng
            if budget is not None and self._map_pending == "made":
                self._map_pending = "next"
                return shown
            self._set_environment(eng)  # the next call: the map, whatever its budget
            self._map_pending = None
            if budget is not None:
                return shown
        lk = self.rendered_look
        # the engine turns and scales them by the look (its yaw, tilt and intensities)
        eng.set_lights(self.map_lights, to_area_lights(self.placed))
        eng.set_look(lk)
        eng.render(budget, display)
        if not eng.complete:
            return self.outgoing if self.outgoing is not None else eng
        if self.outgoing is not None:
            self.outgoing.release()  # the new person's first frame is complete
            self.outgoing = None
        if lk.shadows == "refined" and not eng.refined_current:
            if not self.refined.start(eng, self.scene):
                self.look = replace(self.look, shadows="soft")
        return eng

    def _render_preview(self, eng: Engine, hard: bool, budget: float | None, display: bool, full: bool = False) -> Engine:
        lk = self.rendered_look
        shadows = ("hard" if hard else "soft") if lk.shadows in ("soft", "refined") else lk.shadows
        eng.set_lights(self.map_lights, to_area_lights(self.placed))
        # the drag preview leaves the light scattered under the skin out (unless ``full``): ~20 ms a
        # frame for a change of at most 2 % at a face's steepest edges (docs/photos.md)
        eng.set_look(replace(lk, shadows=shadows, skin=lk.skin and full))
        eng.render(budget, display)
        return eng

    # ------------------------------------------------------------------ refined shadows
    @property
    def refining(self) -> bool:
        return self.refined.running

    @property
    def refine_error(self) -> str:
        return self.refined.error

    def poll_refinement(self) -> bool:
        """A finished refinement handed to the final engine (:meth:`RefinedShadows.poll`); True when the frame changed."""
        return self.refined.poll(self.final, self.look.shadows == "refined")

    def release(self):
        self.refined.stop()
        self.final.release()
        self.previews.release()
        if self.outgoing is not None:
            self.outgoing.release()
        self.outgoing = None
