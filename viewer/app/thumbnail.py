"""The environment map's thumbnail in the panel: the map as its light arrives now (turned by the
look's yaw and tilt), with a dot on every light (the map's and the user's). A click on it is a
direction towards a light (:meth:`MapThumbnail.direction_at`)."""

from __future__ import annotations

import numpy as np

from ..envmap import EnvMap, direction_to_uv, uv_to_direction
from ..imageio import linear_to_srgb
from ..median_cut import LUMINANCE

WIDTH = 256  # texels across (height: half)


def thumbnail_pixels(env: EnvMap, yaw: float, tilt: float) -> np.ndarray:
    """(WIDTH / 2, WIDTH, 3) uint8 display sRGB of ``env`` (already at most WIDTH wide) turned by
    (yaw, tilt): its median luminance to mid grey, then Reinhard's x / (1 + x), so a sun 1e5 times
    the sky is a bright disc, not the whole picture."""
    pixels = env.rotated(yaw, tilt).pixels.astype(np.float64)
    lum = np.nan_to_num(pixels @ LUMINANCE, nan=0.0, posinf=0.0)
    mid = float(np.median(lum[lum > 0])) if np.any(lum > 0) else 1.0
    x = np.clip(np.nan_to_num(pixels, nan=0.0, posinf=0.0) * (0.18 / mid), 0.0, None)
    return (np.clip(linear_to_srgb(x / (1.0 + x)), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


class MapThumbnail:
    """The GL texture the panel draws, made again only when the map or the look's turn changes."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.texture = None
        self._key = None
        self._small: tuple[int, EnvMap] | None = None  # (id of the full map's pixels, it downsampled)

    def update(self, environment: np.ndarray, yaw: float, tilt: float):
        key = (id(environment), yaw, tilt)
        if key == self._key:
            return self.texture
        if self._small is None or self._small[0] != id(environment):
            self._small = (id(environment), EnvMap(environment).downsampled(WIDTH))
        small = self._small[1]
        pixels = thumbnail_pixels(small, yaw, tilt)
        h, w = pixels.shape[:2]
        if self.texture is None or self.texture.size != (w, h):
            if self.texture is not None:
                self.texture.release()
            self.texture = self.ctx.texture((w, h), 3, dtype="f1")
        self.texture.write(np.ascontiguousarray(pixels).tobytes())
        self._key = key
        return self.texture

    @staticmethod
    def direction_at(u: float, v: float) -> np.ndarray:
        """The direction towards the light arriving through the thumbnail's point (u, v) in [0, 1]."""
        return uv_to_direction((min(max(u, 0.0), 1.0), min(max(v, 0.0), 1.0)))

    @staticmethod
    def points(directions: np.ndarray) -> np.ndarray:
        """(N, 2) thumbnail coordinates in [0, 1] of directions towards lights."""
        return direction_to_uv(np.asarray(directions, dtype=np.float64).reshape(-1, 3))

    def release(self):
        if self.texture is not None:
            self.texture.release()
            self.texture = None
