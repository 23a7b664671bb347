"""A clip's per-frame maps made steady: each frame's maps blended with the frame before's, carried
along the optical flow, wherever the flow holds.

The networks see every frame afresh, so the same cheek gets a slightly different normal, depth and
albedo in each: relit, the person's shading shimmers. For frame t, every map M (albedo, specular,
roughness, normal, depth at the work resolution; the soft matte at the frame's) becomes

    M'_t = (1 - KEEP) M_t + KEEP W(M'_{t-1})

where W carries frame t-1's steadied map to frame t along the backward flow (:mod:`viewer.photo.flow`,
computed on the photo), and only where the flow passes its forward-backward check, the photo carried
along it matches the frame's (``PHOTO_MATCH``: a running woman's blurred profile passed the first test
with a wrong flow, and her lips were drawn twice) and the person was there in both frames: a limb
that moves in front of the body, or appears, keeps its own values (no smear). An exponential
filter of ``KEEP`` = 0.6 leaves a quarter of a still pixel's frame-to-frame noise variance,
(1 - KEEP) / (1 + KEEP), and follows a real change within a few frames (half of it in 1.4
frames). The first frame of a shot starts afresh.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from viewer.photo.flow import backward_flow, dis_flow, resized_flow, shrunk_grey, warp
from viewer.resize import resize

KEEP = 0.6  # the previous frame's share where the flow holds
FLOW_SIDE = 640  # the flow is computed on the photo shrunk to this longer side (DIS at 720p: ~3x the time)
PHOTO_MATCH = 10.0  # grey levels (of 255): the photo carried along the flow must match the frame's this closely


HOLE = 5  # pixels: a hole in where the flow holds up to this wide is filled (grain, a sensor's noise)
EDGE_SIGMA = 1.5  # pixels: the blend's weight falls off over a few pixels at the edge of where the flow fails


def smooth_weight(held: np.ndarray) -> np.ndarray:
    """(H, W) float32 in [0, 1]: where the flow holds, as a smooth weight. The flow's checks fail at
    single pixels of a grainy photo (a noisy render's sparkles, high ISO): blending there and not beside
    them gave the maps pixel-scale steps between carried and fresh values, and a step in the depth casts
    a shadow (a relit synthetic clip came out speckled with black dots). So holes up to ``HOLE`` pixels
    wide are closed, and the weight falls off smoothly (``EDGE_SIGMA``) where a larger region fails (a
    limb moving in front: the weight is 0 there and at the region's edge, rising to 1 over ~2 sigma
    inside the region where it holds, so nothing is blended where the flow failed)."""
    import cv2

    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (HOLE, HOLE))
    closed = cv2.morphologyEx(held.astype(np.uint8), cv2.MORPH_CLOSE, kernel).astype(np.float32)
    return np.clip(2.0 * cv2.GaussianBlur(closed, (0, 0), EDGE_SIGMA) - 1.0, 0.0, 1.0)


class SteadyMaps:
    """Fed a clip's scenes in order (:meth:`steady`), returns each with its maps steadied."""

    def __init__(self, keep: float = KEEP):
        self.keep = keep
        self.flow = dis_flow()
        self._previous = None  # (grey photo at the flow's size, the steadied scene)
        self.shot = None

    def restart(self) -> None:
        """A new shot (or a frame lost): the next frame starts afresh."""
        self._previous = None

    def carry(self, scene, frame_photo: np.ndarray, shot: int | None = None) -> None:
        """Take ``scene`` (already steadied: a frame finished by an earlier run) as the frame before
        the next one."""
        if shot != self.shot:
            self.shot = shot
        self._previous = (shrunk_grey(frame_photo, FLOW_SIDE)[0], scene)

    def steady(self, scene, frame_photo: np.ndarray, shot: int | None = None):
        """``scene`` (a frame's, with its frame layer) with its maps blended along the flow from the
        previous frame's; ``frame_photo``: the frame's photo (H, W, 3) uint8 at the frame's size.
        Returns (the scene, the share of the person's work pixels carried from the frame before)."""
        if shot != self.shot:
            self.restart()
            self.shot = shot
        small = shrunk_grey(frame_photo, FLOW_SIDE)[0]
        previous, self._previous = self._previous, None
        if previous is None or previous[0].shape != small.shape:
            self._previous = (small, scene)
            return scene, 0.0
        back, held = backward_flow(self.flow, small, previous[0])
        # and where the photo carried along the flow is the photo: a fast limb's or face's flow can pass
        # the forward-backward check and still be wrong (motion blur), and blending there draws a ghost
        held &= np.abs(small.astype(np.float32) - warp(previous[0].astype(np.float32), back)) <= PHOTO_MATCH
        old = previous[1]
        maps, carried = self._blend_maps(scene, old, back, held)
        out = replace(scene, **maps)
        if scene.frame is not None and old.frame is not None and old.frame.alpha.shape == scene.frame.alpha.shape:
            out = replace(out, frame=replace(scene.frame, alpha=self._blend_alpha(scene.frame.alpha, old.frame.alpha, back, held)))
        out = out.validate()
        self._previous = (small, out)
        return out, carried

    def _blend_maps(self, scene, old, back: np.ndarray, held: np.ndarray) -> tuple[dict, float]:
        """(the work maps blended where the flow holds and the person is in both frames, the share of
        the person's pixels blended)."""
        size = (scene.width, scene.height)
        flow = resized_flow(back, size)
        ok = resize(held.astype(np.float32), size) > 0.99
        # the work frame's size follows the person's size in the frame (a few pixels from frame to frame):
        # the frame before's maps brought to this one's (both span the photo's whole field of view)
        same = old.mask.shape == scene.mask.shape
        was = warp(resize(old.mask.astype(np.float32), size) if not same else old.mask.astype(np.float32), flow) > 0.99
        k = self.keep * smooth_weight(ok) * (scene.mask & was)
        here = k > 0
        maps = {}
        for name in ("albedo", "specular", "roughness", "depth", "normal"):
            new = getattr(scene, name)
            before = np.ascontiguousarray(getattr(old, name), np.float32)
            carried = warp(before if same else resize(before, size), flow)
            kk = k[..., None] if new.ndim == 3 else k
            maps[name] = ((1 - kk) * new + kk * carried).astype(np.float32)
        n = maps["normal"]
        length = np.linalg.norm(n, axis=2, keepdims=True)
        maps["normal"] = np.where(scene.mask[..., None], n / np.maximum(length, 1e-6), scene.normal).astype(np.float32)
        maps["depth"] = np.where(scene.mask, np.maximum(maps["depth"], 1e-3), scene.depth).astype(np.float32)
        for name in ("albedo", "specular", "roughness"):
            maps[name] = np.clip(maps[name], 0.0, 1.0)
        return maps, float(here.sum() / max(int(scene.mask.sum()), 1))

    def _blend_alpha(self, alpha: np.ndarray, old: np.ndarray, back: np.ndarray, held: np.ndarray) -> np.ndarray:
        """The soft matte blended where the flow holds (at the frame's size) and where the frame's own
        matte and the one carried both have the person: the blend steadies the edge's soft values and
        never adds coverage (a flow that holds in a plain background yet is wrong there carried a block
        of the old curtain in beside a hip) nor cuts a hole (a limb that appears)."""
        h, w = alpha.shape
        flow = resized_flow(back, (w, h))
        carried = warp(old.astype(np.float32), flow)
        ok = resize(held.astype(np.float32), (w, h)) > 0.99
        k = self.keep * smooth_weight(ok) * ((alpha > 0) & (carried > 0))
        return np.clip((1 - k) * alpha + k * carried, 0.0, 1.0).astype(np.float32)
