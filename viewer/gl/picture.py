"""How the engine's final picture is made and read back: one interface, two kinds.

- :class:`ImagePicture`, a scene without a frame layer: the composite's HDR, toned at the maps'
  resolution over its background (``DisplayPass``).
- :class:`FramePicture`, a scene with a frame layer (a photo's bundle): the shading sums upsampled
  to the photo's frame, over the frame's background (``FrameBackgroundPass``,
  ``FrameMipmapsPass``, ``SkinScatterPass`` where the frame has skin, ``FrameCompositePass``).

The engine (the scheduler) decides when the picture is stale and hands it what it draws from: a
:class:`PictureInputs` of the composite, the look shown and the composite's terms. Each kind owns
its passes' GL objects and says which passes it has (``passes``) so that the engine can track
what makes them stale.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from viewer.gl.display_pass import DisplayPass
from viewer.gl.frame_pass import (
    OUTPUT_BACKGROUND_DISPLAY,
    OUTPUT_BACKGROUND_HDR,
    OUTPUT_COMPOSITED_HDR,
    OUTPUT_PERSON_HDR,
    FrameBackgroundPass,
    FrameCompositePass,
    FrameMipmapsPass,
)
from viewer.gl.skin_pass import SkinScatterPass

BANDS = 4  # a budgeted frame composite's bands (at 2048 pixels with one llvmpipe thread the whole is ~110 ms)


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

    def restart(self):
        """Nothing to start again: the picture is drawn in one unit."""

    def draw(self, i: PictureInputs, whole: bool, work=None) -> bool:
        if work is not None and work.spent("display"):
            return False
        self.last.run(i.composite.hdr, i.look, i.background, box=None if whole else self.box)
        return True

    def read_person(self, i: PictureInputs) -> np.ndarray:
        return self.kit.read(i.composite.hdr, 4)

    def read_output(self, i: PictureInputs) -> np.ndarray:
        return self.last.read_hdr_output(i.composite.hdr, i.look, i.background)

    def read_shading(self, i: PictureInputs, sheen_detail: bool = True):
        raise ValueError("the scene has no frame layer")

    def read_background_display(self, i: PictureInputs):
        raise ValueError("the scene has no frame layer")

    def read_background_hdr(self, i: PictureInputs):
        raise ValueError("the scene has no frame layer")

    def release(self):
        self.last.release()


class FramePicture:
    has_frame = True

    def __init__(self, kit, frame, camera, ground, background_camera=None):
        # background_camera: the lens the map behind is seen through, when not the scene's (a clip's shot keeps one)
        self.background = FrameBackgroundPass(kit, frame, background_camera or camera)
        self.mipmaps = FrameMipmapsPass(kit)
        self.scatter = SkinScatterPass(kit, frame) if SkinScatterPass.applies(frame) else None
        self.last = FrameCompositePass(kit, frame, self.background.photo, ground, camera.width, self.scatter)
        self.passes = (self.mipmaps, *([self.scatter] if self.scatter else []), self.background, self.last)
        self._bands = None  # a budgeted draw under way: the background's and the frame's bands drawn

    def _ready(self, i: PictureInputs):
        """The frame composite's inputs up to date: the background and the shading sums' mipmaps."""
        if i.stale(self.background.name):
            self.background.run(i.look, i.background, i.environment)
            i.ran(self.background)
        if i.stale(self.mipmaps.name):
            self.mipmaps.run(i.composite.shading)
            i.ran(self.mipmaps)
        if self.scatter is not None and i.stale(self.scatter.name):
            self.scatter.run(i.composite.shading[0], i.look.skin)
            i.ran(self.scatter)

    def restart(self):
        """Something changed since a budgeted draw was left part-way: its bands start again."""
        self._bands = None

    def draw(self, i: PictureInputs, whole: bool, work=None) -> bool:
        """Draw the frame (``whole``, else over the matte's box). With ``work`` (a budgeted render,
        :class:`viewer.gl.work_budget.WorkBudget`) the background (when stale) and the whole frame are drawn
        in ``BANDS`` bands of rows each, one unit a band, the frame into the back image, shown
        (swapped to the front) once all its bands are drawn, so no frame of a window shows half of
        one; False when the budget ran out first (the bands drawn are kept for the next call; the
        engine calls :meth:`restart` first when anything changed meanwhile)."""
        if work is None:
            self._bands = None
            self._ready(i)
            self.last.run(i.composite.shading, self.background.image, i.terms, i.look, i.background,
                          box=None if whole else self.last.box)
            return True
        if self._bands is None:
            self._bands = {"background": 0, "frame": 0}
        b = self._bands
        if i.stale(self.background.name):
            while b["background"] < BANDS:
                if work.spent("frame_background"):
                    return False
                self.background.run(i.look, i.background, i.environment, (b["background"], BANDS))
                b["background"] += 1
            i.ran(self.background)
            b["frame"] = 0
        if i.stale(self.mipmaps.name):
            if work.spent("frame_mipmaps"):
                return False
            self.mipmaps.run(i.composite.shading)
            i.ran(self.mipmaps)
            b["frame"] = 0
        if self.scatter is not None and i.stale(self.scatter.name):
            if work.spent("skin_scatter"):
                return False
            self.scatter.run(i.composite.shading[0], i.look.skin)
            i.ran(self.scatter)
            b["frame"] = 0
        while b["frame"] < BANDS:
            if work.spent("frame_band"):
                return False
            self.last.draw_band(i.composite.shading, self.background.image, i.terms, i.look, i.background, b["frame"], BANDS)
            b["frame"] += 1
        self.last.swap()
        self._bands = None
        return True

    def _read(self, i: PictureInputs, terms, output_mode: int, sheen_detail: bool = True) -> np.ndarray:
        self._ready(i)
        return self.last.read(i.composite.shading, self.background.image, terms, i.look, i.background, output_mode,
                              sheen_detail)

    def read_person(self, i: PictureInputs) -> np.ndarray:
        return self._read(i, i.terms, OUTPUT_PERSON_HDR)

    def read_output(self, i: PictureInputs) -> np.ndarray:
        return self._read(i, i.terms, OUTPUT_COMPOSITED_HDR)

    def read_background_display(self, i: PictureInputs) -> np.ndarray:
        """(H, W, 4) float32 in [0, 1]: the display image with no person in it (nor their shadow)."""
        return self._read(i, i.terms, OUTPUT_BACKGROUND_DISPLAY)

    def read_background_hdr(self, i: PictureInputs) -> np.ndarray:
        """(H, W, 4) float32: the HDR with no person in it, as :meth:`read_output` (alpha 1, or 0 transparent)."""
        return self._read(i, i.terms, OUTPUT_BACKGROUND_HDR)

    def read_shading(self, i: PictureInputs, sheen_detail: bool = True):
        """The diffuse and specular sums at the frame, upsampled as the frame composite does
        (``sheen_detail`` False: the specular without the albedo's fine detail, the sum the lights make)."""
        return (self._read(i, (1.0, 0.0, True), OUTPUT_PERSON_HDR)[..., :3],
                self._read(i, (0.0, 1.0, False), OUTPUT_PERSON_HDR, sheen_detail)[..., :3])

    def release(self):
        for p in (self.last, self.background, self.scatter):
            if p is not None:
                p.release()
