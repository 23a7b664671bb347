"""What the synthetic people wear or carry besides their outfit, since real photos have it and the
first datasets did not: a crossbody bag or a backpack (meshes of their own, hung on the posed body),
their straps, a watch, a necklace and a knit cap (bands of the body's surface, which
:func:`viewer.lab.data.materials.classify` finds and :func:`viewer.lab.data.humans.dress` stands
off the skin as it does clothes)."""

from __future__ import annotations

import numpy as np

from viewer.lab.data.geometry import icosphere, vertex_normals
from viewer.lab.data.materials import CLOTH_KINDS, Accessories, _color, fbm

# width, height and thickness (metres)
BAG_SIZE = {"crossbody": (0.24, 0.18, 0.07), "backpack": (0.28, 0.38, 0.13)}
GOLD, SILVER = (0.80, 0.55, 0.22), (0.62, 0.62, 0.60)  # linear albedo of the metals


def sample_accessories(rng: np.random.Generator, seated: bool) -> Accessories:
    """A crossbody bag (15 %) or a backpack (10 %; neither when ``seated``: the bag would sit in the
    lap), a watch (25 %), a necklace (15 %), a knit cap (10 %); bags in dark leather or any colour."""
    u = rng.uniform
    kind = u()
    bag = None if seated else "crossbody" if kind < 0.15 else "backpack" if kind < 0.25 else None
    leather = u() < 0.5
    colour = tuple(float(v) for v in np.array([0.06, 0.04, 0.03]) * u(0.5, 3.0)) if leather else _color(rng)
    specular, (r0, r1) = CLOTH_KINDS["leather" if leather else "synthetic"]
    watch = tuple(float(v) for v in (SILVER if u() < 0.5 else _color(rng))) if u() < 0.25 else None
    necklace = (GOLD if u() < 0.5 else SILVER) if u() < 0.15 else None
    cap = _color(rng) if u() < 0.10 else None
    return Accessories(bag=bag, bag_side=1.0 if u() < 0.5 else -1.0, bag_color=colour, bag_specular=specular,
                       bag_roughness=float(u(r0, r1)), watch=watch, necklace=necklace, cap=cap)


def bag_mesh(a: Accessories, pos: np.ndarray, normals: np.ndarray, fields: np.ndarray, heads: dict, scale: float):
    """The bag of ``a`` hung on the posed, dressed body (camera-space ``pos`` and ``normals``, whose
    rest-pose ``fields`` come from :func:`viewer.lab.data.humans.build_body`; ``scale`` turns metres
    into the mesh's units): a rounded box (a superellipsoid of exponent 6) with its thin side
    against the body and its height along the camera's up, which is the body's. A crossbody bag
    hangs from the side-front of the hip at the end of its strap, a backpack from the middle of
    the back. Returns (vertices, faces, normals, albedo, specular, roughness) per vertex, or None
    without a bag."""
    if a.bag is None:
        return None
    rest = fields[:, 0:3]
    body = (fields[:, 3] < 0.5) & (fields[:, 5] < 0.5)
    z_hip = 0.5 * (heads["upperleg01.L"][2] + heads["upperleg01.R"][2])
    w, h, t = BAG_SIZE[a.bag]
    if a.bag == "crossbody":
        level = body & (np.abs(rest[:, 2] - (z_hip + 0.07)) < 0.015)
        out = np.radians(40.0)  # between the side and the front
        score = a.bag_side * rest[:, 0] * np.cos(out) - rest[:, 1] * np.sin(out)
        drop = 0.5 * h - 0.02  # its top 2 cm above the strap's end
    else:
        level = body & (np.abs(rest[:, 2] - 0.5 * (heads["spine01"][2] + heads["spine03"][2])) < 0.015) & (np.abs(rest[:, 0]) < 0.03)
        score = rest[:, 1]  # anny's +y is the back
        drop = 0.0
    k = np.flatnonzero(level)[np.argmax(score[level])]
    up = np.array([0.0, 1.0, 0.0])
    out_dir = normals[k] - (normals[k] @ up) * up
    out_dir = out_dir / max(np.linalg.norm(out_dir), 1e-9)
    across = np.cross(up, out_dir)  # (across, up, out) is right-handed: the sphere's winding is kept
    centre = pos[k] + scale * ((0.5 * t + 0.008) * out_dir - drop * up)
    d, faces = icosphere(4)
    q = d / (np.abs(d) ** 6).sum(axis=1, keepdims=True) ** (1.0 / 6.0)
    local = q * np.array([0.5 * w, 0.5 * h, 0.5 * t])
    verts = centre + scale * (local[:, :1] * across + local[:, 1:2] * up + local[:, 2:3] * out_dir)
    # colour noise of the material, and a darker flap over the top two thirds of the outer face
    shade = 1.0 + 0.08 * fbm(local, 0.03, 29)
    flap = (q[:, 2] > 0.5) & (q[:, 1] > -0.35)
    shade = np.where(flap, 0.8 * shade, shade)
    albedo = np.clip(np.array(a.bag_color)[None, :] * shade[:, None], 0.0, 1.0)
    n = len(verts)
    return (verts, faces, vertex_normals(verts, faces), albedo, np.full(n, a.bag_specular), np.full(n, a.bag_roughness))
