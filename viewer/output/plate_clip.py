"""A clip's person put into a plate, frame by frame (``relight render CLIP --plate PLATE -o OUT.mp4``).

The person is placed once, on the clip's first frame with them in it (``--at``, ``--height`` and the
plate's own horizon, as a photo is: :func:`viewer.plate.placement.plate_transform`), and that one
scale and offset carries every frame into the plate: the person walks across the plate as they walk
across their own frame (their camera held still), never jumping to stand where the placement says
frame after frame. Each frame is the person relit (:class:`viewer.output.clip_render.ClipPictures`'s
render, the plate's look) composited into the plate as a still is
(:func:`viewer.output.plate_render.composite_frame`: the ground's shadow, the contact shadow,
the plate's defocus where the feet first stand and its grain, the same grain pattern every frame as
the still plate's own); a frame where no one was found is the plate alone.
"""

from __future__ import annotations

import numpy as np

from viewer.output.clip_render import ClipPictures
from viewer.output.plate_render import composite_frame, read_person
from viewer.plate.loader import Plate
from viewer.plate.match import feet_blur, grain_levels, with_grain
from viewer.plate.placement import Placement, plate_transform

COMPOSITE_VERSION = 2  # bump when the composite changes what a part shows (2: the plate's people in front hide the person)


class PlatePictures(ClipPictures):
    """The clip's frames in ``plate`` (:class:`ClipPictures`' arguments, then the plate, where the person
    stands on it and its horizon; ``cut_allowed``: their feet may be out of their frame, ``--height`` given)."""

    def __init__(self, *args, plate: Plate, place: Placement, horizon: float | None = None, cut_allowed: bool = False, **kwargs):
        super().__init__(*args, **kwargs)
        self.plate, self.place, self.horizon = plate, place, horizon
        first = self.frames.people[0]
        scene = self.frames.scene(first, self.sizes)
        self.anchor = scene.frame.alpha if scene.frame is not None else scene.mask.astype(np.float32)  # places every frame
        self.transform = plate_transform(self.anchor, place, plate.size, self.bundle.scene_path(first), cut_allowed)
        self.blur, self.grain = feet_blur(plate.srgb, place), grain_levels(plate.srgb)
        self.size = plate.size
        self._mattes: dict = {}  # the mattes of the plate's people found standing in front, by index

    def key(self) -> str:
        """The plate's pixels and where the person stands on it: a part made on another is not reused."""
        import hashlib

        return hashlib.sha256(self.plate.srgb.tobytes() + repr((self.plate.size, self.transform, self.horizon,
                                                                COMPOSITE_VERSION)).encode()).hexdigest()[:16]

    def picture(self, index: int) -> np.ndarray:
        """(H, W, 3) uint8: output frame ``index``, the plate's size."""
        from viewer.files.imageio import linear_to_srgb

        index, person = self.frames.shown(index)
        if person != index:  # no one in this frame: the plate as it is
            return self.plate.srgb
        engine, _ = self._render(index, self._look(index, index))
        result, _, _ = composite_frame(read_person(engine), self.plate, self.place, self.blur, self.horizon, self.anchor,
                                       cut_allowed=True, mattes=self._mattes)
        srgb = with_grain(np.clip(linear_to_srgb(result.image), 0.0, 1.0), result.person[..., 3], self.grain)
        return (srgb * 255.0 + 0.5).astype(np.uint8)
