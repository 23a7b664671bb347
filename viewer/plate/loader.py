"""A plate file: the photo the person is put into, upright, in sRGB, and its camera's field of view.

The photo is read as every photo is (:func:`viewer.photo.frames.read_image_u8`: EXIF
orientation, ICC colours converted, 16-bit reduced to 8 with a note). The field of view comes from
the EXIF 35-mm-equivalent focal length (tag 0xA405, which phones and most cameras write), else
``DEFAULT_FOCAL_35`` (with a note), a standard lens's. It is taken to span the frame's longer side as
36 mm would (the standard defines it by the diagonal, 43.3 mm: a 4:3 photo's field of view comes out
about 2 degrees wider than its own). A plate over ``MAX_PLATE_PIXELS`` is refused in one line from its header, before it is decoded (its
linear copies alone would take gigabytes).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import srgb_to_linear
from viewer.files.kinds import wrong_kind
from viewer.scene.camera import focal_pixels

DEFAULT_FOCAL_35 = 35.0  # mm, 35-mm equivalent: what a plate without a focal length in its EXIF is taken as
MIN_PLATE_PX = 16  # a plate smaller than this a side holds no light to read
MAX_PLATE_PIXELS = 60_000_000  # 60 MP: a larger plate is refused (give a smaller copy)
CLIP = 250  # of 255: a channel this high was clipped by the camera (or the JPEG)
PANORAMA_ASPECT = 2.5  # a longer side this many times the shorter (a phone's panorama), or exactly 2:1 (equirectangular): no plate


SRGB_TO_LINEAR = srgb_to_linear(np.arange(256) / 255.0)  # the 256 levels' linear values: a plate is linearized by lookup


@dataclass(frozen=True)
class Plate:
    """A plate: ``srgb`` (H, W, 3) uint8, upright; ``focal_35`` the 35-mm-equivalent focal length (mm)
    and where it came from (``focal_source``: "exif" or "default"); ``source`` the file; ``front`` (H, W)
    float32, what of it the user marked as standing in front of the person (:mod:`viewer.plate.front_mask`), or None."""

    srgb: np.ndarray
    focal_35: float
    focal_source: str
    source: str | None = None
    front: np.ndarray | None = None

    @property
    def size(self) -> tuple[int, int]:
        return int(self.srgb.shape[1]), int(self.srgb.shape[0])

    @property
    def focal_px(self) -> float:
        """The focal length in the plate's pixels (its longer side spans 36 mm of a 35-mm frame)."""
        return focal_pixels(self.focal_35, self.size)

    def focal_at(self, size: tuple[int, int]) -> float:
        """The focal length in the pixels of the plate resized to ``size`` (w, h), by its width."""
        return self.focal_px * size[0] / self.size[0]

    def within(self, longest: int) -> Plate:
        """The plate no longer than ``longest`` pixels on its longer side (shrunk by area; the same lens: its
        focal length spans the longer side), or itself: a video's frames on a plate are the plate's size."""
        from viewer.resize import resize, scaled_size

        if max(self.size) <= longest:
            return self
        size = scaled_size(self.size, longest)
        front = None if self.front is None else np.clip(resize(self.front, size), 0.0, 1.0).astype(np.float32)
        smaller = Plate(resize(self.srgb, size), self.focal_35, self.focal_source, self.source, front)
        if "people" in self.__dict__:  # found on the whole plate: the same people (their landmarks are fractions)
            from viewer.photo.segmentation import Person

            smaller.__dict__["people"] = [Person(np.clip(resize(p.segmentation, size), 0.0, 1.0), p.landmarks) for p in self.people]
        return smaller

    @cached_property
    def people(self) -> list:
        """The people standing in the plate (:func:`viewer.photo.segmentation.find_people`: their
        segmentation and landmarks), found once: the camera's height and what stands in front of the
        person both read them."""
        from viewer.photo.segmentation import find_people

        return find_people(self.srgb, self.source)

    @cached_property
    def linear(self) -> np.ndarray:
        """(H, W, 3) float32 linear RGB in [0, 1] (a table lookup of the 256 sRGB levels), made once: the
        light's estimate and the composite both read it."""
        return SRGB_TO_LINEAR[self.srgb]


def read_plate(path, notes: list, front=None) -> Plate:
    """The plate at ``path``; one line naming the file for what cannot be a plate (not an image, a video,
    fewer than ``MIN_PLATE_PX`` pixels a side, a panorama: landscape, exactly 2:1 or wider than ``PANORAMA_ASPECT``).
    ``front``: the user's mask of what stands in front of the person (:func:`viewer.plate.front_mask.read_front`)."""
    from viewer.photo.frames import read_image_u8

    wrong = wrong_kind(path, "a plate (a photo to put the person into)")
    if wrong is not None:
        raise wrong
    lens: dict = {}
    image = read_image_u8(path, "plate", notes, lens=lens, max_pixels=MAX_PLATE_PIXELS)
    if image.shape[0] < MIN_PLATE_PX or image.shape[1] < MIN_PLATE_PX:
        raise InputError(path, f"is {image.shape[1]}x{image.shape[0]} pixels: a plate needs at least {MIN_PLATE_PX} a side")
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=-1)
    elif image.shape[-1] == 4:
        notes.append("the plate's alpha channel is ignored (a plate is the whole picture behind the person)")
    image = np.ascontiguousarray(image[..., :3])
    focal, source = lens.get("focal_35mm"), "exif"
    if focal is None:
        focal, source = DEFAULT_FOCAL_35, "default"
        notes.append(f"the plate's EXIF gives no focal length: taken as {DEFAULT_FOCAL_35:g} mm (35-mm equivalent)")
    aspect = image.shape[1] / image.shape[0]  # a panorama is landscape: a portrait photo twice as tall is a plate
    if abs(aspect - 2.0) < 0.01 or aspect > PANORAMA_ASPECT:
        raise InputError(path, f"is {image.shape[1]}x{image.shape[0]}: " + ("an equirectangular panorama (2:1)" if aspect < 2.1 else
                               "a panorama") + ", not a plate; give a panorama as the map (--env) and a photo as the plate")
    if front is not None:
        from viewer.plate.front_mask import read_front

        return Plate(image, focal, source, str(path), read_front(front, image, notes))
    return Plate(image, focal, source, str(path))
