"""The ground the person stands on: where the feet touch it, the plane through them, and the points
near it that darken it on contact.

A photo shows the ground under a standing person only where the feet are in the frame. The
person's lowest parts, when the mask ends above the frame's bottom edge, are the **contacts**: the
lowest pixel of each of the (at most two) largest blobs of the mask's bottom band (a foot, a shoe,
both feet together, the hem of a long dress; the back foot is often higher in the image). Their
camera-space points, read from the depth map a little inside the blob, fix the **plane**: through both contacts with the normal
nearest the camera's up (the network's depth rarely puts both soles at one height; a level plane at
the lower one would leave the other foot hanging), or level through the one contact; never tilted
more than ``MAX_TILT`` degrees (then level through the lower). Without contacts the plane is level
at the person's lowest point, as the ground shadow was before (``relight render --ground``).

The **contact points** are the person's points within ``CONTACT_HEIGHT`` of the plane near a
contact, each with the area it stands for (:data:`MAX_CONTACT_POINTS` at most): each light's
shadow on the plane (shaders/ground_shadow.frag.glsl) is at least the share of that light they
hide, each light standing for a cone of the sky (:func:`contact_spread`): the occlusion at the feet
that the shadow maps' bias and resolution leave out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

BAND = 0.08  # of the person's height: the bottom band where the feet are looked for
EDGE_MARGIN = 2  # pixels: a mask reaching this close to the frame's bottom edge is cut off there (no feet)
MIN_BLOB = 0.1  # a blob of the bottom band smaller than this share of the largest is not a foot
MAX_TILT = 12.0  # degrees: a plane through two contacts tilted more than this is replaced by a level one
CONTACT_HEIGHT = 0.04  # metres above the plane: the person's points that darken the ground on contact
CONTACT_REACH = 0.25  # metres from a contact: the points kept for the contact shadow
MAX_CONTACT_POINTS = 64
# CONTACT_HEIGHT and SPREAD: chosen against Mitsuba (relight bench ground, docs/engine.md): 4 cm and
# a quarter of a light's share of the sphere bring the darkest ground at the feet from 0.30 to 0.19
# of its light under the mountain map (truth 0.16), the contact region's mean error 0.067 -> 0.064
SPREAD = 0.25
CONTACT_BOUND = 0.5  # metres: beyond this from every contact point, what they hide is left out (under 1 %)
UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class GroundPlane:
    """The plane ``normal . p = offset`` (camera space, metres; ``normal`` unit, pointing up), the
    feet's contact points on it (k, 3) (k = 0: no feet in the frame) and the contact shadow's
    points (m, 4): position and the area (m^2) each stands for."""

    normal: np.ndarray
    offset: float
    contacts: np.ndarray
    contact_points: np.ndarray

    @property
    def feet(self) -> bool:
        """Whether the person's feet are in the frame (the ground shadow is on by default then)."""
        return len(self.contacts) > 0

    @property
    def below_camera(self) -> bool:
        """A plane the camera looks down on."""
        return self.offset < 0.0


def contacts(mask: np.ndarray) -> list[tuple[int, int]]:
    """(x, y) pixels of the mask where the feet touch the ground: the lowest pixel (the one of the
    lowest row nearest its middle) of each of the two largest blobs of the mask's bottom band (``BAND`` of the
    person's height; a blob under ``MIN_BLOB`` of the largest is not a foot); none when the mask
    reaches the frame's bottom edge (the feet are cut off) or is empty."""
    import cv2

    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0 or rows[-1] >= mask.shape[0] - 1 - EDGE_MARGIN:
        return []
    height = rows[-1] - rows[0] + 1
    top = max(int(rows[-1] - max(BAND * height, 2)), 0)
    band = np.zeros(mask.shape, np.uint8)
    band[top:rows[-1] + 1] = mask[top:rows[-1] + 1]
    count, labels, stats, _ = cv2.connectedComponentsWithStats(band, connectivity=8)
    if count <= 1:
        return []
    areas = stats[1:, cv2.CC_STAT_AREA]
    out = []
    for i in np.argsort(-areas)[:2]:
        if areas[i] < MIN_BLOB * areas.max():
            continue
        ys, xs = np.nonzero(labels == i + 1)
        bottom = ys.max()
        lowest = xs[ys == bottom]  # (a blob whose lowest row is in pieces: its middle may not be the mask's)
        out.append((int(lowest[np.argmin(np.abs(lowest - lowest.mean()))]), int(bottom)))
    return out


def _level(y: float) -> tuple[np.ndarray, float]:
    return UP.copy(), float(y)


def ground_plane(scene) -> GroundPlane:
    """The ground of a scene (its mask, depth and camera)."""
    points = scene.points()
    feet = contacts(scene.mask)
    inside = points[scene.mask]
    found = []
    for x, y in feet:
        # the contact's point: the median of the blob's pixels just above its lowest one (the
        # outline's own depth is the least sure)
        y0 = max(y - 3, 0)
        near = scene.mask[y0:y + 1, max(x - 3, 0):x + 4]
        block = points[y0:y + 1, max(x - 3, 0):x + 4][near]
        p = np.median(block, axis=0)
        p[1] = block[:, 1].min()  # the sole: the lowest of them
        found.append(p)
    found = np.array(found, np.float64).reshape(-1, 3)
    if len(found) == 2:
        t = found[1] - found[0]
        t = t / max(np.linalg.norm(t), 1e-9)
        n = UP - UP.dot(t) * t
        if np.linalg.norm(n) > 1e-6 and math.degrees(math.acos(min(n.dot(UP) / np.linalg.norm(n), 1.0))) <= MAX_TILT:
            n = n / np.linalg.norm(n)
            normal, offset = n, float(n.dot(found[0]))
        else:
            normal, offset = _level(found[:, 1].min())
    elif len(found) == 1:
        normal, offset = _level(found[0, 1])
    else:
        normal, offset = _level(float(inside[:, 1].min()) if len(inside) else 0.0)
    return GroundPlane(normal, offset, found.astype(np.float32), _contact_points(scene, inside, found, normal, offset))


def _contact_points(scene, inside: np.ndarray, found: np.ndarray, normal: np.ndarray, offset: float) -> np.ndarray:
    """(m, 4): of the person's points ``inside`` (n, 3), those within CONTACT_HEIGHT above the
    plane and CONTACT_REACH of a contact, thinned to MAX_CONTACT_POINTS, each with the area of the
    pixels it stands for."""
    if not len(found):
        return np.zeros((0, 4), np.float32)
    p = inside.astype(np.float64)
    height = p @ normal - offset
    near = (height <= CONTACT_HEIGHT) & (np.min(np.linalg.norm(p[:, None] - found[None], axis=-1), axis=1) <= CONTACT_REACH)
    p = p[near]
    if not len(p):
        return np.zeros((0, 4), np.float32)
    pixel_area = (p[:, 2] / scene.camera.focal_px) ** 2  # a pixel's footprint at its depth (m^2)
    if len(p) > MAX_CONTACT_POINTS:
        keep = np.linspace(0, len(p) - 1, MAX_CONTACT_POINTS).round().astype(int)
        pixel_area = np.full(MAX_CONTACT_POINTS, pixel_area.sum() / MAX_CONTACT_POINTS)
        p = p[keep]
    return np.column_stack([p, pixel_area]).astype(np.float32)


def contact_spread(lights: int) -> float:
    """The angle (radians) of the sky each of ``lights`` area lights stands for, a quarter of the
    side of its share of the sphere: the feet's contact points hide a light from the plane within
    a Gaussian lobe of at least this sigma (shaders/ground_shadow.frag.glsl)."""
    return SPREAD * math.sqrt(4.0 * math.pi / max(int(lights), 1))
