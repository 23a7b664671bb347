"""The silhouette prior (viewer/nets/silhouette.py): exact outline normals, distances, any mask."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from viewer.nets.silhouette import DISTANCE_SCALE, RADIUS, silhouette_maps


def _disc(size=256, radius=80.0, centre=(128.0, 125.0)):
    rows, cols = np.mgrid[0:size, 0:size] + 0.5
    return (rows - centre[0]) ** 2 + (cols - centre[1]) ** 2 <= radius**2, rows - centre[0], cols - centre[1]


def test_a_disc_has_outward_tangent_normals_at_its_outline_and_faces_the_camera_inside():
    mask, dr, dc = _disc()
    m = silhouette_maps(mask)
    r = np.hypot(dr, dc)
    padded = np.pad(mask, 1)
    outline = mask & ~(padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:])  # a 4-neighbour outside
    n = m[..., :2]
    # within half a pixel of the outline the tube of radius 7.7 px turns at least 65 degrees away
    assert np.linalg.norm(n[outline], axis=1).min() > 0.9
    # outward: camera x along the columns, camera y against the rows
    outward = np.stack([dc, -dr], -1) / np.maximum(r, 1e-9)[..., None]
    cos = (n[outline] * outward[outline]).sum(1) / np.linalg.norm(n[outline], axis=1)
    angle = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    assert np.median(angle) < 3.0 and angle.max() < 10.0  # (the worst: corners of the raster's staircase)
    deep = mask & (r < 80 - RADIUS * 256 - 2)
    assert np.abs(n[deep]).max() < 1e-6  # past the tube's radius the inflation faces the camera
    centre = m[128, 125, 2]
    assert abs(centre / DISTANCE_SCALE * 256 - 79.5) < 1.5  # the distance to the outline, in image heights
    assert (m[~mask] == 0).all()


def test_empty_and_full_masks():
    assert (silhouette_maps(np.zeros((32, 32), bool)) == 0).all()
    full = silhouette_maps(np.ones((32, 32), bool))
    assert np.isfinite(full).all() and np.abs(full[..., :2]).max() < 1e-6 and full[..., 2].max() <= DISTANCE_SCALE


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 64), st.integers(1, 64), st.integers(0, 2**31 - 1), st.floats(0.05, 0.95))
def test_any_mask_gives_finite_bounded_channels(h, w, seed, fill):
    mask = np.random.default_rng(seed).uniform(size=(h, w)) < fill
    m = silhouette_maps(mask)
    assert m.shape == (h, w, 3) and m.dtype == np.float32 and np.isfinite(m).all()
    assert (np.linalg.norm(m[..., :2], axis=-1) <= 1.0 + 1e-6).all()
    assert (m[~mask] == 0).all() and (m[..., 2] >= 0).all() and m[..., 2].max() <= DISTANCE_SCALE + 1e-6
