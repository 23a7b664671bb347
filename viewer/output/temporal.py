"""Temporal stability of relit sequences (the paper's dRMSE) and a reference-free flicker measure.

dRMSE at step k compares how a sequence changes with how its reference changes:
``sqrt(mean((I[t+k] - I[t] - (R[t+k] - R[t]))^2))`` over all t and pixels, so a method whose
error is the same in every frame scores 0 and one whose error jumps from frame to frame does not.
The flicker ratio needs no reference: ``mean|I[t+1] - 2 I[t] + I[t-1]| / mean|I[t+1] - I[t]|``,
small for motion that changes steadily and about 2 (or more) for frame-to-frame flicker.
Frames are (T, H, W, C) arrays, compared as given (display images in [0, 1] in this project).
"""

from __future__ import annotations

import numpy as np

STEPS = (1, 2, 4)


def _check(frames: np.ndarray, min_frames: int) -> np.ndarray:
    frames = np.asarray(frames, dtype=np.float64)
    if frames.ndim < 3 or frames.shape[0] < min_frames:
        raise ValueError(f"need a (T, H, W[, C]) sequence of at least {min_frames} frames, got shape {frames.shape}")
    return frames


def drmse(frames, reference, steps=STEPS) -> dict[int, float]:
    """dRMSE of ``frames`` against ``reference`` (same shape) at each step."""
    frames = _check(frames, max(steps) + 1)
    reference = _check(reference, max(steps) + 1)
    if frames.shape != reference.shape:
        raise ValueError(f"sequence {frames.shape} and reference {reference.shape} differ in shape")
    out = {}
    for k in steps:
        d = (frames[k:] - frames[:-k]) - (reference[k:] - reference[:-k])
        out[k] = float(np.sqrt(np.mean(d * d)))
    return out


def flicker_ratio(frames) -> float:
    """Mean absolute second difference over mean absolute first difference (see the module doc)."""
    frames = _check(frames, 3)
    first = np.abs(np.diff(frames, axis=0)).mean()
    second = np.abs(np.diff(frames, n=2, axis=0)).mean()
    return float(second / first) if first > 0 else 0.0
