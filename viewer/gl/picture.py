"""How the engine's final picture is made and read back: one interface, two kinds.

- :class:`ImagePicture`, a scene without a frame layer: the composite's HDR, toned at the maps'
  resolution over its background (``DisplayPass``).
- :class:`FramePicture`, a scene with a frame layer (a photo's bundle): the shading sums upsampled
  to the photo's frame, over the frame's background (``FrameBackgroundPass``,
  ``FrameMipmapsPass``, ``FrameCompositePass``).

The engine (the scheduler) decides when the picture is stale and hands it what it draws from: a
:class:`PictureInputs` of the composite, the look shown and the composite's terms. Each kind owns
its passes' GL objects and says which passes it has (``passes``) so that the engine can track
what makes them stale.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .display_pass import DisplayPass
from .frame_pass import FrameBackgroundPass, FrameCompositePass, FrameMipmapsPass, OUTPUT_COMPOSITED_HDR, OUTPUT_PERSON_HDR


@dataclass
class PictureInputs:
    composite: object  # the CompositePass: its HDR (work resolution) and its shading sums
    look: object  # the look as shown (Engine.shown_look)
    background: str  # the look's background
    terms: tuple  # (diffuse weight, specular weight, unit albedo) of the composite
    environment: object  # the scene's environment texture (the frame's background reads it)
    stale: Callable[[str], bool]  # whether a pass's result is stale
    ran: Callable[[object], None]  # a pass brought its result up to date


class ImagePicture:
    has_frame = False

    def __init__(self, kit, resources, size, camera, ground):
        self.kit, self.box = kit, resources.mask_box
        self.last = DisplayPass(kit, resources, size, camera, ground)  # the pass that draws the picture
        self.passes = (self.last,)

    def draw(self, i: PictureInputs, whole: bool):
        self.last.run(i.composite.hdr, i.look, i.background, box=None if whole else self.box)

    def read_person(self, i: PictureInputs) -> np.ndarray:
        return self.kit.read(i.composite.hdr, 4)

    def read_output(self, i: PictureInputs) -> np.ndarray:
        return self.last.read_hdr_output(i.composite.hdr, i.look, i.background)

    def read_shading(self, i: PictureInputs):
        raise ValueError("the scene has no frame layer")

    def release(self):
        self.last.release()


class FramePicture:
    has_frame = True

    def __init__(self, kit, frame, camera, ground):
        self.background = FrameBackgroundPass(kit, frame, camera)
        self.mipmaps = FrameMipmapsPass(kit)
        self.last = FrameCompositePass(kit, frame, self.background.photo, ground)
        self.passes = (self.mipmaps, self.background, self.last)

    def _ready(self, i: PictureInputs):
        """The frame composite's inputs up to date: the background and the shading sums' mipmaps."""
        if i.stale(self.background.name):
            self.background.run(i.look, i.background, i.environment)
            i.ran(self.background)
        if i.stale(self.mipmaps.name):
            self.mipmaps.run(i.composite.shading)
            i.ran(self.mipmaps)

    def draw(self, i: PictureInputs, whole: bool):
        self._ready(i)
        self.last.run(i.composite.shading, self.background.image, i.terms, i.look, i.background == "transparent",
                      box=None if whole else self.last.box)

    def _read(self, i: PictureInputs, terms, output_mode: int) -> np.ndarray:
        self._ready(i)
        return self.last.read(i.composite.shading, self.background.image, terms, i.look, i.background == "transparent",
                              output_mode)

    def read_person(self, i: PictureInputs) -> np.ndarray:
        return self._read(i, i.terms, OUTPUT_PERSON_HDR)

    def read_output(self, i: PictureInputs) -> np.ndarray:
        return self._read(i, i.terms, OUTPUT_COMPOSITED_HDR)

    def read_shading(self, i: PictureInputs):
        """The diffuse and specular sums at the frame, upsampled as the frame composite does."""
        return (self._read(i, (1.0, 0.0, True), OUTPUT_PERSON_HDR)[..., :3],
                self._read(i, (0.0, 1.0, False), OUTPUT_PERSON_HDR)[..., :3])

    def release(self):
        for p in (self.last, self.background):
            p.release()
