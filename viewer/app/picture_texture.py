"""A picture the window draws from a texture of its own (a clip's frame with no one in it, a frame
relit ahead): written again only when what it shows changes (its key), made again only for another
size. One piece for every such picture, so each releases its GL texture the same way."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


class PictureTexture:
    def __init__(self, ctx):
        self.ctx = ctx
        self.texture = None  # the texture last written (None before one was)
        self._key = None  # what it holds

    def show(self, key, picture: Callable[[], np.ndarray]):
        """The texture holding ``picture()`` (uint8 RGB, (H, W, 3)), called only when ``key`` is not the
        one it holds."""
        if self._key != key:
            rgb = picture()
            h, w = rgb.shape[:2]
            if self.texture is None or self.texture.size != (w, h):
                self.release()
                self.texture = self.ctx.texture((w, h), 3, dtype="f1")
            self.texture.write(np.ascontiguousarray(rgb).tobytes())  # row 0 at v = 0, as the engine's display (Engine.display)
            self._key = key
        return self.texture

    def release(self) -> None:
        if self.texture is not None:
            self.texture.release()
            self.texture = None
            self._key = None
