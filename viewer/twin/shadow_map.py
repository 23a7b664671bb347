"""Shadow maps: the depth mesh rasterized orthographically from each light, vectorized in torch.

A light's shadow map has R x R texels; a point with shadow-map coordinates (u, v, z) (see
:mod:`viewer.scene.shadow_space`) lies at pixel position x = u R, y = v R, and texel (i, j) covers
[j, j + 1) x [i, i + 1), so row i = floor(v R) and row 0 is at v = 0 (an OpenGL texture's first
row). Each texel stores the smallest normalised depth z of the triangles covering its centre
(j + 0.5, i + 0.5), z interpolated linearly over the triangle as OpenGL does under an orthographic
projection, and the frame's ``empty_depth`` where no triangle covers it. Both faces of every
triangle are drawn (no culling), and the interpolated z is clamped to the triangle's own depth range
(which only matters for slivers, where rounding could overshoot).

Coverage follows a top-left style tie rule so that a texel centre lying exactly on an edge shared by
two triangles belongs to exactly one of them: each edge function is evaluated from coefficients
computed in one canonical direction (from the lower to the higher vertex index) and negated exactly
for the other, so neighbouring triangles agree bit for bit and the mesh is watertight.

The rasterizer works on (light, triangle) pairs grouped into buckets of equal bounding-box size
(powers of two per axis); each bucket enumerates its candidate texels by broadcasting, tests them
and keeps the nearest depth with ``scatter_reduce(amin)``. No gradients flow through it.
"""

from __future__ import annotations

import torch

from viewer.scene.depth_mesh import DepthMesh
from viewer.twin.shadow_geometry import LightFrames

CANDIDATES_PER_CHUNK = 1 << 22  # texel candidates tested at once (bounds the memory)


def project_vertices(vertices: torch.Tensor, frames: LightFrames) -> torch.Tensor:
    """Shadow-map coordinates (u, v, z) of the mesh vertices for every light: (N, K, 3)."""
    m = frames.matrix().to(vertices.dtype)
    return torch.einsum("nij,kj->nki", m[:, :3, :3], vertices) + m[:, None, :3, 3]


def _ceil_log2(n: torch.Tensor) -> torch.Tensor:
    """ceil(log2(n)) of positive integers, elementwise (int64)."""
    return torch.ceil(torch.log2(n.double())).long()


def _edge_coefficients(xy: torch.Tensor, triangles: torch.Tensor, orientation: torch.Tensor):
    """Inside-positive edge functions w = a x + b y + c of every triangle's three edges.

    ``xy`` (N, K, 2) vertex pixel positions, ``triangles`` (T, 3), ``orientation`` (N, T) = sign of
    the signed area. Returns a, b, c (N, T, 3) and ``own`` (N, T, 3): whether a centre lying exactly
    on the edge belongs to this triangle (the inward normal points to +x, or to +y when vertical).
    """
    a_list, b_list, c_list = [], [], []
    for e in range(3):
        ia, ib = triangles[:, e], triangles[:, (e + 1) % 3]
        forward = ia < ib
        lo_idx = torch.where(forward, ia, ib)
        hi_idx = torch.where(forward, ib, ia)
        p, q = xy[:, lo_idx], xy[:, hi_idx]  # canonical direction: lower index -> higher index
        a = p[..., 1] - q[..., 1]
        b = q[..., 0] - p[..., 0]
        c = (q[..., 1] - p[..., 1]) * p[..., 0] - (q[..., 0] - p[..., 0]) * p[..., 1]
        sign = torch.where(forward, orientation, -orientation)
        a_list.append(a * sign)
        b_list.append(b * sign)
        c_list.append(c * sign)
    a, b, c = torch.stack(a_list, -1), torch.stack(b_list, -1), torch.stack(c_list, -1)
    own = (a > 0) | ((a == 0) & (b > 0))
    return a, b, c, own


@torch.no_grad()
def rasterize_depth(uvz: torch.Tensor, triangles: torch.Tensor, resolution: int,
                    empty_depth: float = 1.0) -> torch.Tensor:
    """Shadow maps (N, R, R) of triangles ``triangles`` (T, 3) with vertex coordinates ``uvz`` (N, K, 3).

    Texels that no triangle covers hold ``empty_depth``.
    """
    n_lights = uvz.shape[0]
    res = int(resolution)
    device, dtype = uvz.device, uvz.dtype
    out = torch.full((n_lights * res * res,), float(empty_depth), dtype=dtype, device=device)
    if triangles.numel() == 0 or n_lights == 0:
        return out.reshape(n_lights, res, res)
    triangles = triangles.to(device=device, dtype=torch.long)
    xy = uvz[..., :2] * res
    v = xy[:, triangles]  # (N, T, 3, 2)
    zt = uvz[..., 2][:, triangles]  # (N, T, 3)
    e1, e2 = v[:, :, 1] - v[:, :, 0], v[:, :, 2] - v[:, :, 0]
    area = e1[..., 0] * e2[..., 1] - e2[..., 0] * e1[..., 1]  # twice the signed area, (N, T)
    a, b, c, own = _edge_coefficients(xy, triangles, torch.sign(area))
    # depth plane z = z0 + gx (x - x0) + gy (y - y0), kept inside the triangle's depth range
    dz1, dz2 = zt[..., 1] - zt[..., 0], zt[..., 2] - zt[..., 0]
    safe = torch.where(area == 0, torch.ones_like(area), area)
    gx = (dz1 * e2[..., 1] - dz2 * e1[..., 1]) / safe
    gy = (dz2 * e1[..., 0] - dz1 * e2[..., 0]) / safe
    # texel centres inside the bounding box: j + 0.5 in [xmin, xmax], clamped to the map
    lo = torch.ceil(v.amin(dim=2) - 0.5).clamp(min=0).long()  # (N, T, 2) = (j0, i0)
    hi = torch.floor(v.amax(dim=2) - 0.5).clamp(max=res - 1).long()
    size = hi - lo + 1
    light_idx, tri_idx = torch.nonzero((area != 0) & (size > 0).all(dim=-1), as_tuple=True)
    if light_idx.numel() == 0:
        return out.reshape(n_lights, res, res)
    # one row per drawn (light, triangle) pair
    params = torch.cat([a, b, c, v[:, :, 0], zt[..., :1], gx[..., None], gy[..., None],
                        zt.amin(dim=-1, keepdim=True), zt.amax(dim=-1, keepdim=True)], dim=-1)[light_idx, tri_idx]
    own, lo, size = own[light_idx, tri_idx], lo[light_idx, tri_idx], size[light_idx, tri_idx]
    first_texel = (light_idx * res + lo[:, 1]) * res + lo[:, 0]
    bucket = _ceil_log2(size[:, 0]) * 64 + _ceil_log2(size[:, 1])  # (log2 width, log2 height) of the box
    for key in torch.unique(bucket).tolist():
        w_b, h_b = 1 << (key // 64), 1 << (key % 64)
        cols = torch.arange(w_b, device=device)[None, None, :]  # (1, 1, w)
        rows = torch.arange(h_b, device=device)[None, :, None]  # (1, h, 1)
        members = torch.nonzero(bucket == key).squeeze(1)
        for sel in members.split(max(1, CANDIDATES_PER_CHUNK // (w_b * h_b))):
            a0, a1, a2, b0, b1, b2, c0, c1, c2, x0, y0, z0, dzdx, dzdy, zmin, zmax = params[sel].T[..., None, None]
            own_e = own[sel].T[..., None, None]
            j0, i0 = lo[sel, 0, None, None], lo[sel, 1, None, None]
            x = (j0 + cols).to(dtype) + 0.5  # (B, 1, w) texel centres
            y = (i0 + rows).to(dtype) + 0.5  # (B, h, 1)
            inside = (cols < size[sel, 0, None, None]) & (rows < size[sel, 1, None, None])
            for e, (ea, eb, ec) in enumerate(((a0, b0, c0), (a1, b1, c1), (a2, b2, c2))):
                w = ea * x + eb * y + ec
                inside = inside & ((w > 0) | ((w == 0) & own_e[e]))
            depth = (z0 + dzdx * (x - x0) + dzdy * (y - y0)).clamp(min=zmin, max=zmax)
            texel = first_texel[sel, None, None] + rows * res + cols
            out.scatter_reduce_(0, texel[inside], depth[inside], reduce="amin")
    return out.reshape(n_lights, res, res)


def shadow_maps(mesh: DepthMesh, frames: LightFrames, resolution: int) -> torch.Tensor:
    """The lights' shadow maps (N, R, R) of a depth mesh, on the frames' device."""
    device, dtype = frames.direction.device, frames.direction.dtype
    vertices = torch.as_tensor(mesh.vertices, dtype=dtype, device=device)
    triangles = torch.as_tensor(mesh.triangles, device=device).long()
    with torch.no_grad():
        uvz = project_vertices(vertices, frames)
    return rasterize_depth(uvz, triangles, resolution, frames.empty_depth)
