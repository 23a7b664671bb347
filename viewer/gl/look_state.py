"""What the engine shows apart from the lights: the user's :class:`~viewer.scene.look.Look`, the map
behind the person (uploaded blurred as the look's backdrop asks), and which of the passes' inputs a
new look changes. The engine marks those inputs changed; this module decides nothing else."""

from __future__ import annotations

import math

import numpy as np

from viewer.errors import InputError
from viewer.gl.scene_resources import SceneResources
from viewer.lighting.median_cut import LUMINANCE
from viewer.scene.backdrop import blurred_map
from viewer.scene.bundle import Scene
from viewer.scene.look import AUTO, EXPOSURE_LIMIT, Look

SHADING_VIEWS = ("diffuse_shading", "specular_shading")  # one term of the composite, shown alone
DISPLAY_FIELDS = ("yaw", "tilt", "exposure", "tonemap", "background", "background_color", "compare")
BACKGROUND_FIELDS = ("yaw", "tilt", "background", "background_color")  # what the frame background shows


class LookState:
    """The engine's look and the map behind it (``Engine.look``, ``Engine.set_environment``)."""

    def __init__(self, scene: Scene, resources: SceneResources, feet: bool):
        self.scene, self.resources, self.feet = scene, resources, feet
        self.look = Look(background="color", background_color=(0.0, 0.0, 0.0))  # no background until one is set
        self._environment, self._uploaded_sigma = None, None  # the map as given; the blur it was uploaded with

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

    def set_environment(self, pixels: np.ndarray) -> list[str]:
        """A new map behind the person (H, W, 3) linear RGB; returns the inputs it changed."""
        self._environment = np.asarray(pixels, dtype=np.float32)
        return self._upload()

    def _upload(self) -> list[str]:
        sigma = self.backdrop_sigma
        self.resources.set_environment(blurred_map(self._environment, sigma))
        self._uploaded_sigma = sigma
        return ["environment"]

    def check(self, look: Look, light_count: int):
        """What a look may ask of this scene: a photo behind it only if the bundle has one, the
        shadow view of a light that exists."""
        if look.background == "photo" and self.scene.background is None and self.scene.frame is None:
            raise InputError(None, "this scene bundle has no background image (background.png)")
        if look.view == "shadow" and not look.light < light_count:
            raise InputError(None, f"no light {look.light}: there are {light_count}")

    def replace(self, look: Look) -> list[str]:
        """Show ``look`` from now on; returns the passes' inputs it changed, in order."""
        old, terms, ground = self.look, self.composite_terms(), self.ground_shown
        self.look = look
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
