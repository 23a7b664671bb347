"""Optical flow between a clip's frames: OpenCV's DIS (Kroeger et al. 2016: fast, dense, in the
stack's ``opencv-contrib-python``, chosen over Farneback for its accuracy at equal speed), the
warp it defines, and the forward-backward check that tells where it holds (occlusions, a limb
that moved in front, the frame's edge fail it: Sundaram et al. 2010's test)."""

from __future__ import annotations

import numpy as np

from viewer.resize import resize

CONSISTENT = 1.0  # pixels: a forward-backward mismatch beyond this (plus the share below) fails the check
CONSISTENT_SCALE = 0.05  # of the two flows' length


def dis_flow():
    """A DIS flow engine (the medium preset)."""
    import cv2

    return cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)


def grey(rgb: np.ndarray) -> np.ndarray:
    """uint8 grey of an RGB uint8 frame (what the flow is computed on)."""
    import cv2

    return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)


def shrunk_grey(rgb: np.ndarray, side: int) -> tuple[np.ndarray, float]:
    """(grey uint8 of ``rgb`` shrunk so its longer side is at most ``side``, the scale it was shrunk by)."""
    from viewer.resize import resize

    h, w = rgb.shape[:2]
    scale = min(side / max(h, w), 1.0)
    return grey(resize(rgb, (max(round(w * scale), 1), max(round(h * scale), 1)))), scale


def warp(image: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """``image`` sampled at x + flow(x) (bilinear, edges replicated); any number of channels."""
    import cv2

    h, w = flow.shape[:2]
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    return cv2.remap(image, xs + flow[..., 0], ys + flow[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def backward_flow(engine, current: np.ndarray, previous: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the flow from ``current`` to ``previous`` (H, W, 2) float32, where it holds (H, W) bool):
    grey uint8 frames of one size; it holds where the forward-backward check passes and the flow
    lands inside the frame."""
    back = engine.calc(current, previous, None)
    forth_there = warp(engine.calc(previous, current, None), back)
    mismatch = np.linalg.norm(back + forth_there, axis=2)
    length = np.linalg.norm(back, axis=2) + np.linalg.norm(forth_there, axis=2)
    h, w = current.shape
    xs, ys = np.meshgrid(np.arange(w), np.arange(h))
    tx, ty = xs + back[..., 0], ys + back[..., 1]
    inside = (tx >= 0) & (tx <= w - 1) & (ty >= 0) & (ty <= h - 1)
    return back, (mismatch <= CONSISTENT + CONSISTENT_SCALE * length) & inside


def resized_flow(flow: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A flow field brought to ``size`` = (w, h), its vectors scaled with it."""

    h, w = flow.shape[:2]
    out = resize(flow, size, "linear")
    out[..., 0] *= size[0] / w
    out[..., 1] *= size[1] / h
    return out
