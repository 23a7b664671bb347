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
OWN_BACKGROUND = 0.1  # a frame's own matte under this is the background's: the frame before's never lifts it over one half


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
        from viewer.photo.face_track import FaceTrack

        self.keep = keep
        self.flow = dis_flow()
        self.faces = FaceTrack()  # the face's landmarks, smoothed from frame to frame (steady_faces)
        self._previous = None  # (grey photo at the flow's size, the steadied scene)
        self.shot = None
        self._flow = None  # (the frame's photo, what _flow_for made of it): computed once a frame, for the matte and the maps
        self._objects = None  # (H, W) bool: what the frame before was found holding (viewer.photo.matting.confirmed)

    def restart(self) -> None:
        """A new shot (or a frame lost): the next frame starts afresh."""
        self._previous = self._flow = self._objects = None
        self.faces.restart()

    def found_objects(self, objects: np.ndarray | None) -> None:
        """What this frame's matte found the person holding (:attr:`viewer.photo.matting.Matte.objects`),
        for the next frame's :meth:`carried_matte`."""
        self._objects = objects

    def carry(self, scene, frame_photo: np.ndarray, shot: int | None = None) -> None:
        """Take ``scene`` (already steadied: a frame finished by an earlier run) as the frame before
        the next one."""
        if shot != self.shot:
            self.shot = shot
        self._previous, self._flow, self._objects = (shrunk_grey(frame_photo, FLOW_SIDE)[0], scene), None, None
        self.faces.restart()  # (its landmarks are not kept in the bundle: the face's filter starts at the next frame)

    def _flow_for(self, frame_photo: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """(the frame's grey photo at the flow's size; the backward flow from the frame before to it and
        where it holds, as :func:`smooth_weight`; both None with no frame before of that size). It holds
        where it passes the forward-backward check and the photo carried along it matches the frame's
        (a fast limb's or face's flow can pass the first check and still be wrong: motion blur, and
        blending there draws a ghost). Computed once for a frame's photo: its matte and its maps both use it."""
        if self._flow is None or self._flow[0] is not frame_photo:
            small = shrunk_grey(frame_photo, FLOW_SIDE)[0]
            before = self._previous[0] if self._previous is not None else None
            back = weight = None
            if before is not None and before.shape == small.shape:
                back, held = backward_flow(self.flow, small, before)
                held &= np.abs(small.astype(np.float32) - warp(before.astype(np.float32), back)) <= PHOTO_MATCH
                weight = smooth_weight(held)  # at the flow's size, where grain is a pixel or two
            self._flow = (frame_photo, (small, back, weight))
        return self._flow[1]

    def steady_faces(self, faces: list, shot: int | None = None) -> list:
        """The frame's faces (largest first) with the largest one's landmarks smoothed along the clip
        (:class:`viewer.photo.face_track.FaceTrack`; afresh at a new shot)."""
        if shot != self.shot:
            self.faces.restart()
        return self.faces.smooth(faces)

    def carried_matte(self, frame_photo: np.ndarray, shot: int | None = None):
        """The frame before's matte carried to this frame along the flow, and where the flow holds
        (:class:`viewer.photo.trimap.Carried`, at the frame's size), for deciding this frame's outline;
        None for a shot's first frame."""
        from viewer.photo.trimap import Carried

        previous = self._previous if shot == self.shot else None
        if previous is None or previous[1].frame is None:
            return None
        _, back, weight = self._flow_for(frame_photo)
        h, w = frame_photo.shape[:2]
        old = previous[1].frame.alpha
        if back is None or old.shape != (h, w):
            return None
        flow = resized_flow(back, (w, h))
        objects = self._objects
        if objects is not None:
            objects = warp(objects.astype(np.float32), flow) > 0.5 if objects.shape == (h, w) else None
        return Carried(warp(old.astype(np.float32), flow), resize(weight, (w, h)), objects)

    def steady(self, scene, frame_photo: np.ndarray, shot: int | None = None):
        """``scene`` (a frame's, with its frame layer) with its maps blended along the flow from the
        previous frame's; ``frame_photo``: the frame's photo (H, W, 3) uint8 at the frame's size.
        Returns (the scene, the share of the person's work pixels carried from the frame before)."""
        if shot != self.shot:  # a cut: the maps start afresh (the face's filter did, at this frame's faces)
            self._previous = self._flow = None
            self.shot = shot
        small, back, weight = self._flow_for(frame_photo)
        previous, self._previous, self._flow = self._previous, None, None
        if back is None:  # the shot's first frame (or the frame before was another size)
            self._previous = (small, scene)
            return scene, 0.0
        old = previous[1]
        maps, carried = self._blend_maps(scene, old, back, weight)
        out = replace(scene, **maps)
        if scene.frame is not None and old.frame is not None and old.frame.alpha.shape == scene.frame.alpha.shape:
            out = replace(out, frame=replace(scene.frame, alpha=self._blend_alpha(scene.frame.alpha, old.frame.alpha, back, weight)))
        self._previous = (small, out)  # (valid as it is: the blended maps are clipped, the normals unit, zero off the mask)
        return out, carried

    def _blend_maps(self, scene, old, back: np.ndarray, weight: np.ndarray) -> tuple[dict, float]:
        """(the work maps blended where the flow holds (``weight``, :func:`smooth_weight`) and the person
        is in both frames, the share of the person's pixels blended)."""
        size = (scene.width, scene.height)
        flow = resized_flow(back, size)
        ok = np.clip(resize(weight, size), 0.0, 1.0)
        # the work frame's size follows the person's size in the frame (a few pixels from frame to frame):
        # the frame before's maps brought to this one's (both span the photo's whole field of view)
        same = old.mask.shape == scene.mask.shape
        was = warp(resize(old.mask.astype(np.float32), size) if not same else old.mask.astype(np.float32), flow) > 0.99
        k = self.keep * ok * (scene.mask & was)
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

    def _blend_alpha(self, alpha: np.ndarray, old: np.ndarray, back: np.ndarray, weight: np.ndarray) -> np.ndarray:
        """The soft matte blended where the flow holds (at the frame's size) and where the frame's own
        matte and the one carried both have the person: the blend steadies the edge's soft values and
        never adds coverage (a flow that holds in a plain background yet is wrong there carried a block
        of the old curtain in beside a hip) nor cuts a hole (a limb that appears). Nor does it lift over
        one half what this frame's own matte calls background (under ``OWN_BACKGROUND``: a faint 0.05
        blended with a carried 1 came out 0.62, the person's). Within the soft edge it may: a foot's
        edge that dips under one half in one frame was kept by the frame before's (forbidding that too
        made 8 more pieces of matte come and go in 23 frame pairs of a clip, feet and hands in motion)."""
        h, w = alpha.shape
        flow = resized_flow(back, (w, h))
        carried = warp(old.astype(np.float32), flow)
        agree = (alpha > 0) & (carried > 0) & ((alpha >= OWN_BACKGROUND) | (carried <= 0.5))
        k = self.keep * np.clip(resize(weight, (w, h)), 0.0, 1.0) * agree
        return np.clip((1 - k) * alpha + k * carried, 0.0, 1.0).astype(np.float32)
