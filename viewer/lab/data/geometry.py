"""Triangle-mesh helpers for the synthetic humans: spheres, normals, edges, smoothing."""

from __future__ import annotations

import numpy as np


def icosphere(level: int):
    """Unit sphere: vertices (N, 3) and outward counter-clockwise triangles (M, 3)."""
    t = (1.0 + 5.0 ** 0.5) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5),
         (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(level):
        cache, nf = {}, []

        def mid(a, b, cache=cache):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    return np.array(verts), np.array(f, dtype=np.int64)


def vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Area-weighted smooth vertex normals (outward for a counter-clockwise mesh)."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def signed_volume(v: np.ndarray, f: np.ndarray) -> float:
    return float(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6.0)


def mesh_edges(faces: np.ndarray) -> np.ndarray:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.sort(e, axis=1)
    return np.unique(e, axis=0)


def neighbour_mean(values: np.ndarray, edges: np.ndarray, n: int) -> np.ndarray:
    acc = np.zeros((n,) + values.shape[1:])
    cnt = np.zeros(n)
    for a, b in ((0, 1), (1, 0)):
        np.add.at(acc, edges[:, a], values[edges[:, b]])
        np.add.at(cnt, edges[:, a], 1.0)
    cnt = np.maximum(cnt, 1.0).reshape((n,) + (1,) * (values.ndim - 1))
    return acc / cnt


def subdivide(vertices: np.ndarray, faces: np.ndarray, attributes: dict, levels: int = 1):
    """Midpoint subdivision, ``levels`` times: every triangle becomes four, positions stay on the
    original (flat) triangles, and each per-vertex attribute (name -> (V, ...) array) is averaged
    at the new vertices (so it is interpolated linearly, as a rasterizer or ray tracer would).
    Returns (vertices, faces, attributes)."""
    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    attrs = {k: np.asarray(a, np.float64) for k, a in attributes.items()}
    for _ in range(levels):
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        edges, inverse = np.unique(e, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        mid = len(v) + inverse.reshape(3, -1)  # new vertex index of edges (01, 12, 20) of each face
        v = np.concatenate([v, 0.5 * (v[edges[:, 0]] + v[edges[:, 1]])])
        attrs = {k: np.concatenate([a, 0.5 * (a[edges[:, 0]] + a[edges[:, 1]])]) for k, a in attrs.items()}
        a, b, c = f[:, 0], f[:, 1], f[:, 2]
        ab, bc, ca = mid
        f = np.concatenate([np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1), np.stack([c, ca, bc], 1),
                            np.stack([ab, bc, ca], 1)])
    return v, f, attrs
