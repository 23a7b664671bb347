"""The environment map's thumbnail in the panel: the map as its light arrives now, with a dot on
every light (the map's and the user's). A click on it is a direction towards a light
(:meth:`MapThumbnail.direction_at`).

The picture is tone-mapped once per map; the lighting's yaw turns it by shifting the texture's u
(wrapping), which costs nothing per frame while the user drags. Points are placed by the same
mapping: a camera-space direction d is the map's direction R^T d (R: the look's yaw and tilt), drawn
at that map point shifted by the yaw, so picture, dots and clicks agree under any tilt (the
picture is the map turned by the yaw alone).
"""

from __future__ import annotations

import numpy as np

from viewer.files.imageio import linear_to_srgb
from viewer.lighting.envmap import EnvMap, direction_to_uv, uv_to_direction
from viewer.lighting.median_cut import LUMINANCE
from viewer.scene.area_lights import rotation_matrix

WIDTH = 256  # texels across (height: half)


def thumbnail_pixels(env: EnvMap) -> np.ndarray:
    """(H, W, 3) uint8 display sRGB of ``env``: its median luminance to mid grey, then Reinhard's
    x / (1 + x), so a sun 1e5 times the sky is a bright disc, not the whole picture."""
    pixels = np.nan_to_num(env.pixels.astype(np.float64), nan=0.0, posinf=0.0)
    lum = pixels @ LUMINANCE
    mid = float(np.median(lum[lum > 0])) if np.any(lum > 0) else 1.0
    x = np.clip(pixels * (0.18 / mid), 0.0, None)
    return (np.clip(linear_to_srgb(x / (1.0 + x)), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def map_thumbnail(env: EnvMap) -> np.ndarray:
    """The thumbnail's pixels of a map: the mean of f x f blocks, f the whole factor that brings it to
    :data:`WIDTH` texels across or up to twice that (a picture, not light: ``EnvMap.downsampled``'s
    exact solid-angle weights imported scipy, 0.16 s of the frame that showed a new map), the last
    rows and columns a block does not fill left out (2:1 kept). A job's thread makes them for a new
    map, so that frame only uploads them."""
    f = max(env.width // WIDTH, 1)
    n = env.height // f
    blocks = env.pixels[:n * f, :2 * n * f].reshape(n, f, 2 * n, f, 3)
    return thumbnail_pixels(EnvMap(blocks.mean(axis=(1, 3))))


class MapThumbnail:
    """The GL texture the panel draws (made again only for a new map) and the thumbnail's mapping
    between its points and camera-space directions under a look's (yaw, tilt)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.texture = None
        self._source = None  # id of the map's pixels the texture shows
        self._made: tuple | None = None  # (the map's pixels, its thumbnail's) made by a job (:meth:`prepare`)

    def prepare(self, environment: np.ndarray, pixels: np.ndarray):
        """The thumbnail of ``environment``, made elsewhere: :meth:`update` uploads it when that map shows."""
        self._made = (environment, pixels)

    def update(self, environment: np.ndarray):
        if self._source == id(environment):
            return self.texture
        made = self._made
        pixels = made[1] if made is not None and made[0] is environment else map_thumbnail(EnvMap(environment))
        h, w = pixels.shape[:2]
        if self.texture is not None:
            self.texture.release()
        self.texture = self.ctx.texture((w, h), 3, np.ascontiguousarray(pixels).tobytes(), dtype="f1")
        self.texture.repeat_x = True  # the yaw's shift wraps around
        self._source = id(environment)
        return self.texture

    @staticmethod
    def uv_range(yaw: float) -> tuple[tuple[float, float], tuple[float, float]]:
        """The texture's (uv0, uv1) that show the map turned by ``yaw`` (EnvMap.rotated's shift)."""
        shift = yaw / 360.0
        return (shift, 0.0), (1.0 + shift, 1.0)

    @staticmethod
    def direction_at(u: float, v: float, yaw: float, tilt: float) -> np.ndarray:
        """The camera-space direction towards the light arriving through the thumbnail's point
        (u, v) in [0, 1]."""
        world = uv_to_direction((u + yaw / 360.0, min(max(v, 0.0), 1.0)))
        return rotation_matrix(yaw, tilt) @ world

    @staticmethod
    def points(directions, yaw: float, tilt: float) -> np.ndarray:
        """(N, 2) thumbnail points in [0, 1] of camera-space directions towards lights."""
        world = np.asarray(directions, dtype=np.float64).reshape(-1, 3) @ rotation_matrix(yaw, tilt)
        uv = direction_to_uv(world)
        uv[:, 0] = np.mod(uv[:, 0] - yaw / 360.0, 1.0)
        return uv

    def release(self):
        if self.texture is not None:
            self.texture.release()
            self.texture = None
