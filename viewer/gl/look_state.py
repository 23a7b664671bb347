"""What the engine shows: the user's :class:`~viewer.scene.look.Look` applied whole (the lights turned
and scaled by it, its background fallen back to what the scene has), the map behind the person
(uploaded blurred as the look's backdrop asks), and which of the passes' inputs a new look changes.
The engine marks those inputs changed."""

from __future__ import annotations

import math

import numpy as np

from viewer.errors import InputError
from viewer.gl.scene_resources import SceneResources
from viewer.lighting.floor import laid_floor
from viewer.lighting.median_cut import LUMINANCE
from viewer.scene.area_lights import AreaLights
from viewer.scene.backdrop import blurred_map
from viewer.scene.bundle import Scene
from viewer.scene.look import AUTO, EXPOSURE_LIMIT, Look

SHADING_VIEWS = ("diffuse_shading", "specular_shading")  # one term of the composite, shown alone
DISPLAY_FIELDS = ("yaw", "tilt", "camera_height", "exposure", "tonemap", "background", "background_color", "compare")
BACKGROUND_FIELDS = ("yaw", "tilt", "camera_height", "background", "background_color")  # what the frame background shows
LIGHT_FIELDS = ("yaw", "tilt", "intensity", "placed_intensity")  # what turns or scales the lights


class LookState:
    """The engine's look and the map behind it (``Engine.look``, ``Engine.set_environment``)."""

    def __init__(self, scene: Scene, resources: SceneResources, feet: bool):
        self.scene, self.resources, self.feet = scene, resources, feet
        # the look as asked, and as shown: its background fallen back to what the scene has (resolved)
        self.asked = self.look = Look(background="color", background_color=(0.0, 0.0, 0.0))  # no background until one is set
        self._environment, self._uploaded_sigma = None, None  # the map as given; the blur it was uploaded with

    def resolved(self, look: Look) -> Look:
        """``look`` with the background it asks for, or what the scene has: the map behind, else
        the photo's background, else a plain colour."""
        background = look.background
        if background == "environment" and self._environment is None:
            background = "photo" if self.scene.background is not None else "color"
        if background == "photo" and self.scene.background is None:
            background = "color"
        return look if background == look.background else look.replace(background=background)

    def turns(self, look: Look) -> bool:
        """Whether ``look`` turns or scales the lights differently from the current one."""
        return any(getattr(look, f) != getattr(self.asked, f) for f in LIGHT_FIELDS)

    def turned(self, lights: AreaLights, placed: AreaLights | None) -> AreaLights:
        """The lights the engine renders under the current look (:meth:`Look.turned`)."""
        return self.asked.turned(lights, placed)

    @property
    def ground_shown(self) -> bool:
        """Whether the look shows the ground shadow (``Look.ground``, "auto" resolved for this scene)."""
        return self.look.ground_shown(self.feet, self.look.background)

    def composite_terms(self) -> tuple[float, float, bool]:
        """(diffuse weight, specular weight, unit albedo) of the composite: the shading views show
        one term; every other view keeps the relit image (the HDR output) as the switches say."""
        view = self.look.view
        if view == "diffuse_shading":
            return 1.0, 0.0, True
        if view == "specular_shading":
            return 0.0, 1.0, False
        return float(self.look.diffuse), float(self.look.specular), False

    def shown(self, active_intensities) -> Look:
        """The look as the display draws it: its ground "auto" resolved (:attr:`ground_shown`); a
        shading view (albedo 1, or the specular term alone) exposed so that every active light
        (``active_intensities``, RGB each) at once, head-on, is white: under the photo's exposure,
        made for albedos of a few tenths, it would clip to white."""
        look = self.look.replace(ground=self.ground_shown)
        if look.view in SHADING_VIEWS:
            peak = sum(float(i @ LUMINANCE) for i in active_intensities)
            stops = -math.log2(peak) if peak > 0.0 and math.isfinite(peak) else 0.0
            look = look.replace(exposure=float(np.clip(stops, -EXPOSURE_LIMIT, EXPOSURE_LIMIT)))
        return look

    @property
    def backdrop_sigma(self) -> float:
        """The backdrop's blur (radians): the look's, or ("auto") the photo's own background defocus."""
        blur = self.look.backdrop_blur
        if blur == AUTO:
            return self.scene.frame.background_blur if self.scene.frame is not None else 0.0
        return float(np.radians(blur))

    def set_environment(self, pixels: np.ndarray | None) -> list[str]:
        """A new map behind the person (H, W, 3) linear RGB, or None: none (a look lit by a light
        file); returns the inputs it changed (the background too where the look's falls back
        differently). A map that shows no ground gets a floor laid under its horizon
        (:mod:`viewer.lighting.floor`)."""
        had = self._environment is not None
        if pixels is None:
            self._environment = None
            return self.replace(self.asked) if had else []
        self._environment = laid_floor(np.asarray(pixels, dtype=np.float32))  # a map with no ground: a floor behind the feet
        return self._upload() + ([] if had else self.replace(self.asked))

    def _upload(self) -> list[str]:
        sigma = self.backdrop_sigma
        self.resources.set_environment(blurred_map(self._environment, sigma))
        self._uploaded_sigma = sigma
        return ["environment"]

    def check(self, look: Look, light_count: int):
        """What a look may ask of this scene: the shadow view of a light that exists."""
        if look.view == "shadow" and not look.light < light_count:
            raise InputError(None, f"no light {look.light}: there are {light_count}")

    def replace(self, look: Look) -> list[str]:
        """Show ``look`` (:meth:`resolved`) from now on; returns the passes' inputs it changed, in order."""
        old, terms, ground = self.look, self.composite_terms(), self.ground_shown
        self.asked, self.look = look, self.resolved(look)
        look = self.look
        changed = []
        if self._environment is not None and self.backdrop_sigma != self._uploaded_sigma:
            changed += self._upload()
        if self.ground_shown != ground:
            changed.append("ground")
        if look.shadows != old.shadows:
            changed.append("visibility")  # lights whose light pass lacks what the mode needs redo it in render()
        if self.composite_terms() != terms:
            changed.append("terms")
        if look.skin != old.skin:
            changed.append("skin")
        if (look.view, look.light if look.view == "shadow" else 0) != (old.view, old.light if old.view == "shadow" else 0):
            changed.append("view")
        if any(not np.array_equal(getattr(look, f), getattr(old, f)) for f in DISPLAY_FIELDS):
            changed.append("display")
        if any(not np.array_equal(getattr(look, f), getattr(old, f)) for f in BACKGROUND_FIELDS):
            changed.append("background")
        return changed
