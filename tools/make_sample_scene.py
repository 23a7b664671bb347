"""Make the bundled sample scene ``assets/sample_scene/``: a clothed person, rendered exactly.

What it does
------------
1. Poses a human body with the ``anny`` package (``pip install anny==0.6.2 -c constraints.txt``, the
   ``assets`` extra; code Apache-2.0, body data from MakeHuman, CC0) in its ``notoes`` topology (feet
   without toes, for shoes), adding eyeballs (that topology leaves the sockets empty): a standing
   figure with the arms slightly away from the body, elbows a little bent, the left knee bent
   (weight on the right leg) and the head turned a little, so that arms shade the torso and the legs
   shade each other. Clothes and hair get some thickness: the body under the cloth is smoothed
   along the normals and each region stands off the skin by a few millimetres (``STANDOFF``).
2. Places it in the project's camera (``viewer.camera.Camera``: 512x512, 50 mm lens on a 36 mm
   sensor, camera at the origin looking along -z, y up), turned ``--turn`` degrees about the vertical,
   its centre ``--distance`` metres in front of the camera, scaled uniformly so that it spans
   ``--fill`` of the image height (feet near the bottom, head near the top). A real-size person at
   4 m spans only about 60 % of this frame; scaling the body (1.37x) and keeping 4 m gives exactly
   the image of a real-size (1.83 m) person at about 2.9 m, with the depth values the project's
   convention expects (subject centre at ~4 m, as a depth network's output). The scale is printed.
3. Rasterizes the mesh with moderngl (headless EGL, RGBA32F render targets and a depth buffer, no
   supersampling, so nothing is averaged across silhouettes) with ``Camera.projection_matrix``:
   depth = view-space -z of the visible surface at each pixel centre (the value
   ``Camera.unproject`` inverts), normals = smooth area-weighted vertex normals interpolated and
   renormalized, in camera space; mask = covered pixels. The same pass interpolates the rest-pose
   position and a few skinning-weight sums of each vertex.
4. Makes the materials per pixel, procedurally, from those interpolated rest-pose fields (no
   textures ship with anny): a striped shirt with short sleeves, denim-like trousers with a belt,
   skin on the face, neck, forearms and hands, shoes with light soles, short dark hair, eyes.
   Albedo is linear RGB; specular / roughness follow the Disney convention of docs/conventions.md.
5. Checks the depth map against rays cast through pixel centres (as ``Camera.unproject`` defines
   them) into the mesh, writes the bundle with ``viewer.scene.save_scene``, loads it back with
   ``viewer.scene.load_scene`` (which validates it), compares the stored normals with normals computed from the depth map by
   finite differences (median angle printed), and writes a contact sheet of the maps (``--sheet``).

The bundled asset was produced from the project root with::

    .venv/bin/python tools/make_sample_scene.py -o assets/sample_scene --size 512

The first construction of the anny model takes one to two minutes and builds a ~1.7 GB cache in
``ANNY_CACHE_DIR`` (default ``~/.cache/anny``; keep it out of the repository); later runs take
about 6 seconds. The output is deterministic (fixed noise seeds).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from viewer.camera import Camera  # noqa: E402
from viewer.scene import Scene, load_scene, save_scene  # noqa: E402

T0 = time.perf_counter()


def log(msg: str) -> None:
    print(f"[{time.perf_counter() - T0:6.1f} s] {msg}", flush=True)


# ----------------------------------------------------------------------------------------------
# Body
# ----------------------------------------------------------------------------------------------

# anny's phenotypes: gender 0 = male, 1 = female; age 2/3 = young adult, 1 = old
PHENOTYPE = dict(gender=0.15, age=0.7, muscle=0.55, weight=0.5, height=0.45, proportions=0.3)

# Local rotations (rotation vectors in radians, anny's world-aligned "local-ref" axes: x = the
# body's left, y = its back, z = up). Identity is anny's rest A-pose.
POSE = {
    # arms down to ~15 degrees from the body, elbows slightly bent, palms towards the thighs
    "upperarm01.L": (0.0, 0.50, 0.0),
    "upperarm01.R": (0.0, -0.50, 0.0),
    "lowerarm01.L": (0.55, 0.0, 0.25),
    "lowerarm01.R": (0.55, 0.0, -0.25),
    # weight on the right leg: the left knee bent and forward, the left heel lifted a little
    "upperleg01.L": (-0.30, 0.0, -0.08),
    "lowerleg01.L": (0.55, 0.0, 0.0),
    "foot.L": (-0.18, 0.0, 0.0),
    "upperleg01.R": (0.0, 0.04, 0.0),
    # a slight sway of the hips and shoulders, the head turned and tilted a little
    "spine03": (0.0, -0.03, 0.0),
    "spine01": (0.03, 0.02, 0.0),
    "neck01": (0.05, 0.0, 0.0),
    "head": (0.0, 0.05, 0.18),
}

ARM_BONES = ("upperarm", "lowerarm", "wrist", "finger", "metacarpal")
HEAD_BONES = ("neck01", "neck02", "neck03", "head", "eye.L", "eye.R")
EYE_BONES = ("eye.L", "eye.R")
FOOT_BONES = ("foot", "toe")


def build_body():
    """Pose the anny body. Returns posed and rest vertices (anny axes, metres), triangles and the
    per-vertex fields the materials are made from."""
    os.environ.setdefault("ANNY_CACHE_DIR", str(Path.home() / ".cache" / "anny"))
    import torch
    import roma
    import anny

    log(f"building the anny model (cache {os.environ['ANNY_CACHE_DIR']}; the first time takes ~1 min)")
    model = anny.Anny(topology="notoes", local_changes="default")  # feet without toes: shoes
    labels = list(model.bone_labels)
    log(f"anny {anny.__version__}: {model.template_vertices.shape[0]} vertices, {len(labels)} bones")

    dtype = model.dtype
    pose = torch.eye(4, dtype=dtype).repeat(1, len(labels), 1, 1)
    for bone, rotvec in POSE.items():
        pose[0, labels.index(bone), :3, :3] = roma.rotvec_to_rotmat(torch.tensor(rotvec, dtype=dtype))
    with torch.no_grad():
        out = model(pose_parameters=pose, phenotype_kwargs=PHENOTYPE)
    verts = out["vertices"][0].numpy().astype(np.float64)
    rest = out["rest_vertices"][0].numpy().astype(np.float64)
    heads = {b: out["rest_bone_heads"][0, i].numpy().astype(np.float64) for i, b in enumerate(labels)}
    faces = model.faces.numpy().astype(np.int64)
    if faces.shape[1] != 3:
        faces = model.get_triangular_faces().numpy().astype(np.int64)

    # skinning-weight sums of bone groups
    w = model.vertex_bone_weights.numpy().astype(np.float64)
    idx = model.vertex_bone_indices.numpy()

    def group(pred):
        sel = np.array([pred(b) for b in labels])
        return (w * sel[idx]).sum(axis=1)

    w_arm = group(lambda b: b.startswith(ARM_BONES))
    w_head = group(lambda b: b in HEAD_BONES)
    w_eye = group(lambda b: b in EYE_BONES)
    w_foot = group(lambda b: b.startswith(FOOT_BONES))

    # position along each arm in the rest pose: 0 at the shoulder joint, 1 at the wrist
    t_arm = np.zeros(len(rest))
    for side, sign in (("L", 1.0), ("R", -1.0)):
        s, e, wr = heads[f"upperarm01.{side}"], heads[f"lowerarm01.{side}"], heads[f"wrist.{side}"]
        # piecewise: shoulder -> elbow is [0, 0.5], elbow -> wrist is [0.5, 1]
        a1, a2 = e - s, wr - e
        t1 = np.clip(((rest - s) @ a1) / (a1 @ a1), 0.0, 1.0)
        t2 = np.clip(((rest - e) @ a2) / (a2 @ a2), 0.0, 1.5)
        t = np.where(t2 > 0.0, 0.5 + 0.5 * t2, 0.5 * t1)
        on_side = sign * rest[:, 0] > 0.0
        t_arm[on_side] = t[on_side]
    fields = np.stack([rest[:, 0], rest[:, 1], rest[:, 2], w_arm, t_arm, w_head, w_eye, w_foot], axis=1)
    if signed_volume(verts, faces) < 0.0:  # make the triangles counter-clockwise seen from outside
        faces = faces[:, ::-1].copy()

    # this topology has empty eye sockets: add eyeballs, spheres about the eye bones' heads that
    # fill the sockets, moved with the posed eye bones
    rest_poses = out["rest_bone_poses"][0].numpy().astype(np.float64)
    poses = out["bone_poses"][0].numpy().astype(np.float64)
    sphere_v, sphere_f = icosphere(3)
    for side in ("L", "R"):
        k = labels.index(f"eye.{side}")
        centre = heads[f"eye.{side}"]
        radius = np.linalg.norm(rest - centre, axis=1).min() - 2e-4
        ball_rest = centre + radius * sphere_v
        xf = poses[k] @ np.linalg.inv(rest_poses[k])
        ball = ball_rest @ xf[:3, :3].T + xf[:3, 3]
        ball_fields = np.zeros((len(ball), fields.shape[1]))
        ball_fields[:, 0:3] = ball_rest
        ball_fields[:, 5] = 1.0  # head
        ball_fields[:, 6] = 1.0  # eye
        faces = np.concatenate([faces, sphere_f + len(verts)])
        verts = np.concatenate([verts, ball])
        rest = np.concatenate([rest, ball_rest])
        fields = np.concatenate([fields, ball_fields])
    return verts, faces, fields, heads, rest


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

        def mid(a, b):
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


def place_in_camera(verts: np.ndarray, cam: Camera, distance: float, turn_deg: float, fill: float):
    """Anny axes (x left, -y front, z up) -> camera space (x right, y up, z to the camera) with the
    body facing the camera, turned ``turn_deg`` about the vertical, its bounding-box centre at depth
    ``distance`` and scaled so that its projection spans ``fill`` of the image height, centred."""
    to_cam = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # front (-y) -> +z
    a = np.radians(turn_deg)
    rot_y = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    r = rot_y @ to_cam
    b = verts @ r.T
    b = b - 0.5 * (b.min(axis=0) + b.max(axis=0))
    f = cam.focal_px
    cx, cy = cam.center
    s = fill * cam.height * distance / (f * (b[:, 1].max() - b[:, 1].min()))
    t = np.array([0.0, 0.0, -distance])
    for _ in range(20):  # perspective makes the extent depend on the placement: iterate
        p = s * b + t
        u = cx + f * p[:, 0] / -p[:, 2]
        v = cy - f * p[:, 1] / -p[:, 2]
        s *= fill * cam.height / (v.max() - v.min())
        t[0] -= (0.5 * (u.min() + u.max()) - cx) * distance / f
        t[1] += (0.5 * (v.min() + v.max()) - cy) * distance / f
    return s * b + t, r, s


# ----------------------------------------------------------------------------------------------
# Rasterization (moderngl, EGL)
# ----------------------------------------------------------------------------------------------

VERTEX_SHADER = """
#version 450
uniform mat4 proj;
in vec3 in_pos;
in vec3 in_nrm;
in vec4 in_a;
in vec4 in_b;
out vec3 v_pos;
out vec3 v_nrm;
out vec4 v_a;
out vec4 v_b;
void main() {
    v_pos = in_pos;
    v_nrm = in_nrm;
    v_a = in_a;
    v_b = in_b;
    gl_Position = proj * vec4(in_pos, 1.0);
}
"""

FRAGMENT_SHADER = """
#version 450
in vec3 v_pos;
in vec3 v_nrm;
in vec4 v_a;
in vec4 v_b;
layout(location = 0) out vec4 out_geom;  // normal.xyz, depth (view-space -z)
layout(location = 1) out vec4 out_a;
layout(location = 2) out vec4 out_b;
void main() {
    out_geom = vec4(normalize(v_nrm), -v_pos.z);
    out_a = v_a;
    out_b = v_b;
}
"""


def rasterize(cam: Camera, pos: np.ndarray, nrm: np.ndarray, fields: np.ndarray, faces: np.ndarray):
    """Render camera-space triangles; returns depth (H, W), normal (H, W, 3), mask (H, W) and the
    interpolated per-vertex fields (H, W, 8), row 0 at the top."""
    import moderngl

    ctx = moderngl.create_standalone_context(backend="egl", require=450)
    try:
        w, h = cam.width, cam.height
        z = -pos[:, 2]
        near, far = max(0.05, 0.5 * z.min()), 2.0 * z.max()
        prog = ctx.program(vertex_shader=VERTEX_SHADER, fragment_shader=FRAGMENT_SHADER)
        prog["proj"].write(cam.projection_matrix(near, far).T.astype("f4").tobytes())  # column-major
        data = np.concatenate([pos, nrm, fields], axis=1).astype("f4")
        vbo = ctx.buffer(data.tobytes())
        ibo = ctx.buffer(faces.astype("i4").tobytes())
        vao = ctx.vertex_array(prog, [(vbo, "3f 3f 4f 4f", "in_pos", "in_nrm", "in_a", "in_b")], index_buffer=ibo)
        targets = [ctx.texture((w, h), 4, dtype="f4") for _ in range(3)]
        depth_rb = ctx.depth_renderbuffer((w, h))
        fbo = ctx.framebuffer(color_attachments=targets, depth_attachment=depth_rb)
        fbo.use()
        ctx.viewport = (0, 0, w, h)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)  # the mesh is closed; the depth test keeps the nearest surface
        vao.render(moderngl.TRIANGLES)
        ctx.finish()

        def read(i):
            img = np.frombuffer(fbo.read(components=4, attachment=i, dtype="f4"), dtype=np.float32)
            return np.flipud(img.reshape(h, w, 4)).copy()  # GL rows start at the bottom

        geom, a, b = read(0), read(1), read(2)
    finally:
        ctx.release()
    depth = geom[..., 3]
    mask = depth > 0.0
    normal = geom[..., :3]
    normal = np.where(mask[..., None], normal / np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12), 0.0)
    return depth, normal.astype(np.float32), mask, np.concatenate([a, b], axis=-1)


# ----------------------------------------------------------------------------------------------
# Materials
# ----------------------------------------------------------------------------------------------


def value_noise(p: np.ndarray, scale: float, seed: int) -> np.ndarray:
    """Smooth 3D value noise in [-1, 1] at points p (..., 3), lattice spacing ``scale`` metres."""
    rng = np.random.default_rng(seed)
    table = rng.uniform(-1.0, 1.0, size=(64, 64, 64))
    q = p / scale + 32.0
    i = np.floor(q).astype(np.int64)
    fr = q - i
    fr = fr * fr * (3.0 - 2.0 * fr)
    out = np.zeros(p.shape[:-1])
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                wgt = (fr[..., 0] if dx else 1 - fr[..., 0]) * (fr[..., 1] if dy else 1 - fr[..., 1]) * (fr[..., 2] if dz else 1 - fr[..., 2])
                out += wgt * table[(i[..., 0] + dx) % 64, (i[..., 1] + dy) % 64, (i[..., 2] + dz) % 64]
    return out


def fbm(p: np.ndarray, scale: float, seed: int, octaves: int = 3) -> np.ndarray:
    total, amp, norm = np.zeros(p.shape[:-1]), 1.0, 0.0
    for o in range(octaves):
        total += amp * value_noise(p, scale / 2**o, seed + o)
        norm += amp
        amp *= 0.5
    return total / norm


def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


# (albedo linear RGB, specular, roughness)
MATERIALS = {
    "skin": ((0.52, 0.33, 0.25), 0.5, 0.45),
    "hair": ((0.08, 0.05, 0.035), 0.4, 0.35),
    "eye": ((0.50, 0.46, 0.42), 0.6, 0.15),  # sclera ...
    "iris": ((0.12, 0.07, 0.04), 0.6, 0.15),  # ... brown iris ...
    "pupil": ((0.02, 0.02, 0.02), 0.6, 0.15),  # ... and pupil
    "shirt": ((0.40, 0.11, 0.07), 0.3, 0.7),  # brick red ...
    "stripe": ((0.50, 0.45, 0.36), 0.3, 0.7),  # ... with cream stripes
    "trousers": ((0.075, 0.10, 0.17), 0.2, 0.85),  # denim-like blue
    "belt": ((0.07, 0.04, 0.025), 0.45, 0.4),
    "shoe": ((0.04, 0.04, 0.045), 0.5, 0.3),
    "sole": ((0.45, 0.44, 0.42), 0.3, 0.6),
}


def classify(fields: np.ndarray, heads: dict, rest_verts: np.ndarray) -> dict:
    """Material regions (boolean arrays) from rest-pose fields (..., 8) as made by build_body."""
    p = fields[..., 0:3].astype(np.float64)  # rest position, anny axes (x left, -y front, z up)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    w_arm, t_arm, w_head, w_eye, w_foot = (fields[..., k] for k in range(3, 8))

    z_sole = rest_verts[:, 2].min()
    z_ankle = 0.5 * (heads["foot.L"][2] + heads["foot.R"][2])
    z_hip = 0.5 * (heads["upperleg01.L"][2] + heads["upperleg01.R"][2])
    z_spine = heads["spine01"][2]
    z_waist = z_hip + 0.22 * (z_spine - z_hip)
    head_c = heads["head"]
    eye_z = 0.5 * (heads["eye.L"][2] + heads["eye.R"][2])
    head_top = rest_verts[rest_verts[:, 2] > eye_z, 2].max()

    # hair: above a hairline that is high over the forehead and low at the nape, ears left bare
    ry = y - head_c[1]  # > 0 towards the back of the head
    hairline = (eye_z + 0.47 * (head_top - eye_z)) - 0.9 * np.clip(ry + 0.04, 0.0, None)
    hairline = np.maximum(hairline, eye_z - 0.55 * (head_top - eye_z))
    ear = (np.abs(x) > 0.062) & (ry > -0.045) & (ry < 0.025) & (z < eye_z + 0.035)
    hair_noise = value_noise(p * np.array([1.0, 1.0, 0.25]), 0.004, 11)
    is_head = w_head > 0.5
    is_eye = w_eye > 0.5
    is_hair = is_head & ~is_eye & (z > hairline + 0.005 * value_noise(p, 0.012, 13)) & ~ear

    is_arm = (w_arm > 0.5) & ~is_head
    sleeve_end = 0.40 + 0.01 * np.sin(40.0 * np.arctan2(y, x))  # a slightly wavy hem
    is_arm_skin = is_arm & (t_arm > sleeve_end)
    body = ~is_head & ~is_arm
    is_sole = body & (z < z_sole + 0.022)
    is_shoe = body & ~is_sole & ((z < z_ankle + 0.035) | (w_foot > 0.5))
    legs = body & ~is_sole & ~is_shoe & (z < z_waist)
    is_belt = legs & (z > z_waist - 0.035)
    is_trousers = legs & ~is_belt
    is_shirt = ~(is_head | is_arm_skin | is_sole | is_shoe | is_belt | is_trousers)
    is_skin = (is_head & ~is_hair & ~is_eye) | is_arm_skin
    cheeks = is_skin & is_head & (np.abs(z - (eye_z - 0.035)) < 0.025) & (ry < -0.06)
    # on the eyeballs: cosine of the angle from the eye's forward (-y) axis
    d_eye = np.stack([p - heads[f"eye.{side}"] for side in ("L", "R")])
    nearest = np.take_along_axis(d_eye, np.argmin(np.linalg.norm(d_eye, axis=-1), axis=0)[None, ..., None], axis=0)[0]
    gaze = -nearest[..., 1] / np.maximum(np.linalg.norm(nearest, axis=-1), 1e-12)
    iris = is_eye & (gaze > np.cos(np.radians(38.0)))
    pupil = is_eye & (gaze > np.cos(np.radians(16.0)))
    return dict(iris=iris, pupil=pupil, shirt=is_shirt, trousers=is_trousers, belt=is_belt, skin=is_skin, cheeks=cheeks,
                hair=is_hair, shoe=is_shoe, sole=is_sole, eye=is_eye, hair_noise=hair_noise)


def make_materials(fields: np.ndarray, mask: np.ndarray, heads: dict, rest_verts: np.ndarray):
    """Per-pixel albedo, specular and roughness from the interpolated rest-pose fields."""
    p = fields[..., 0:3].astype(np.float64)
    z = p[..., 2]
    r = {k: (v & mask if v.dtype == bool else v) for k, v in classify(fields, heads, rest_verts).items()}
    is_shirt, is_trousers, is_belt, is_skin = r["shirt"], r["trousers"], r["belt"], r["skin"]
    is_hair, is_shoe, is_sole, is_eye, hair_noise = r["hair"], r["shoe"], r["sole"], r["eye"], r["hair_noise"]

    h, w = mask.shape
    albedo = np.zeros((h, w, 3))
    spec = np.zeros((h, w))
    rough = np.zeros((h, w))

    def paint(sel, name, tint=None):
        col, s, r = MATERIALS[name]
        col = np.broadcast_to(np.array(col), (h, w, 3))
        if tint is not None:
            col = col * tint[..., None]
        albedo[sel] = col[sel]
        spec[sel] = s
        rough[sel] = r

    # shirt: horizontal cream stripes (period 7 cm in the rest pose), soft edges, faint weave noise
    phase = np.mod(z / 0.07, 1.0)
    stripe = smoothstep(0.0, 0.06, phase) * (1.0 - smoothstep(0.24, 0.30, phase))
    shirt_col = (1.0 - stripe[..., None]) * np.array(MATERIALS["shirt"][0]) + stripe[..., None] * np.array(MATERIALS["stripe"][0])
    shirt_col *= (1.0 + 0.05 * fbm(p, 0.05, 3))[..., None]
    albedo[is_shirt] = shirt_col[is_shirt]
    spec[is_shirt] = MATERIALS["shirt"][1]
    rough[is_shirt] = MATERIALS["shirt"][2]
    # trousers: low-frequency fading like worn denim
    paint(is_trousers, "trousers", 1.0 + 0.18 * fbm(p * np.array([2.0, 2.0, 0.5]), 0.12, 5))
    paint(is_belt, "belt")
    paint(is_shoe, "shoe", 1.0 + 0.1 * fbm(p, 0.03, 7))
    paint(is_sole, "sole")
    paint(is_skin, "skin", 1.0 + 0.05 * fbm(p, 0.04, 9))
    albedo[r["cheeks"]] *= np.array([1.04, 0.96, 0.96])  # a little redness on the cheeks
    paint(is_hair, "hair", 1.0 + 0.2 * hair_noise)
    paint(is_eye, "eye")
    paint(r["iris"], "iris")
    paint(r["pupil"], "pupil")

    albedo = np.where(mask[..., None], np.clip(albedo, 0.0, 1.0), 0.0).astype(np.float32)
    spec = np.where(mask, spec, 0.0).astype(np.float32)
    rough = np.where(mask, rough, 0.0).astype(np.float32)
    regions = {
        "shirt": is_shirt, "trousers": is_trousers, "belt": is_belt, "skin": is_skin, "hair": is_hair,
        "shoes": is_shoe | is_sole, "eyes": is_eye,
    }
    return albedo, spec, rough, regions


# how far each region stands off the skin (metres, before scaling), and whether the body's shape
# under it is smoothed (cloth hides navel, nipples and the like)
STANDOFF = {"shirt": 0.012, "trousers": 0.016, "belt": 0.018, "shoe": 0.010, "sole": 0.012, "hair": 0.007}
CLOTH = ("shirt", "trousers", "belt", "shoe", "sole")


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


def dress(verts: np.ndarray, faces: np.ndarray, fields: np.ndarray, heads: dict, rest: np.ndarray) -> np.ndarray:
    """Give clothes and hair some thickness: smooth the body under the cloth (Taubin smoothing,
    which does not shrink, along the normals only) and push each region off the skin along the normal by its STANDOFF, with
    short ramps at the hems."""
    n = len(verts)
    edges = mesh_edges(faces)
    regions = classify(fields, heads, rest)
    cloth = np.zeros(n)
    off = np.zeros(n)
    for name in CLOTH:
        cloth[regions[name]] = 1.0
    for name, d in STANDOFF.items():
        off[regions[name]] = d
    for _ in range(3):  # soften the steps at region borders a little (ramps of ~1-2 cm)
        cloth = 0.5 * cloth + 0.5 * neighbour_mean(cloth, edges, n)
        off = 0.5 * off + 0.5 * neighbour_mean(off, edges, n)
    v = verts.copy()
    for _ in range(20):
        for lam in (0.5, -0.53):
            # move along the normal only: sliding along the surface would drag the rest-pose
            # fields (and so the stripes) with the vertices
            nrm = vertex_normals(v, faces)
            lap = neighbour_mean(v, edges, n) - v
            v += (lam * cloth * (lap * nrm).sum(axis=1))[:, None] * nrm
    return v + off[:, None] * vertex_normals(v, faces)


# ----------------------------------------------------------------------------------------------
# Verification
# ----------------------------------------------------------------------------------------------


def normals_from_depth(cam: Camera, depth: np.ndarray, mask: np.ndarray, max_jump: float = 0.02):
    """Central-difference normals of the unprojected depth map; valid where the 4-neighbourhood is
    inside the mask and has no depth jump above ``max_jump`` metres."""
    p = cam.unproject(np.where(mask, depth, 1.0)).astype(np.float64)
    du = np.zeros_like(p)
    dv = np.zeros_like(p)
    du[:, 1:-1] = p[:, 2:] - p[:, :-2]
    dv[1:-1] = p[2:] - p[:-2]
    n = np.cross(dv, du)  # dv points down (-y), du right (+x): dv x du = +z for a fronto-parallel plane
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    valid = mask.copy()
    valid[0] = valid[-1] = False
    valid[:, 0] = valid[:, -1] = False
    for axis in (0, 1):
        for sh in (1, -1):
            nb_m = np.roll(mask, sh, axis=axis)
            nb_d = np.roll(depth, sh, axis=axis)
            valid &= nb_m & (np.abs(nb_d - depth) < max_jump)
    return n, valid


def depth_normal_angle(scene: Scene):
    n_d, valid = normals_from_depth(scene.camera, scene.depth, scene.mask)
    cos = np.clip((n_d * scene.normal).sum(-1), -1.0, 1.0)
    ang = np.degrees(np.arccos(cos))
    return ang, valid


def ray_cast_check(cam: Camera, pos: np.ndarray, faces: np.ndarray, depth: np.ndarray, mask: np.ndarray,
                   count: int = 200, seed: int = 0) -> float:
    """Largest |depth - ray-cast depth| (metres) over ``count`` random mask pixels: the ray through
    each pixel centre (u, v) = (j + 0.5, i + 0.5) is intersected with every triangle (Moller-Trumbore)
    and the nearest hit's -z compared with the depth map."""
    rng = np.random.default_rng(seed)
    rows, cols = np.nonzero(mask)
    pick = rng.choice(len(rows), size=min(count, len(rows)), replace=False)
    a, b, c = pos[faces[:, 0]], pos[faces[:, 1]], pos[faces[:, 2]]
    e1, e2 = b - a, c - a
    f = cam.focal_px
    cx, cy = cam.center
    worst = 0.0
    for i, j in zip(rows[pick], cols[pick]):
        d = np.array([(j + 0.5 - cx) / f, -(i + 0.5 - cy) / f, -1.0])  # ray with unit -z speed
        pv = np.cross(d, e2)
        det = (e1 * pv).sum(1)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = -a
        u = (tv * pv).sum(1) * inv
        qv = np.cross(tv, e1)
        v = (qv * d).sum(1) * inv
        t = (e2 * qv).sum(1) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        if hit.any():
            worst = max(worst, abs(float(t[hit].min()) - float(depth[i, j])))
        else:  # a pixel on the silhouette: the ray grazes an edge
            worst = max(worst, float("inf"))
    return worst


def contact_sheet(scene: Scene, angle: np.ndarray, valid: np.ndarray, path: Path) -> Path:
    from PIL import Image, ImageDraw

    from viewer.imageio import linear_to_srgb

    m = scene.mask
    d = scene.depth
    dmin, dmax = float(d[m].min()), float(d[m].max())
    depth_vis = np.where(m, 1.0 - (d - dmin) / max(dmax - dmin, 1e-6) * 0.85, 0.0)
    light = np.array([-0.45, 0.55, 0.7])
    light /= np.linalg.norm(light)
    shade = np.clip((scene.normal * light).sum(-1), 0.0, None)
    shaded = linear_to_srgb(np.clip(scene.albedo * (0.15 + 1.2 * shade[..., None]), 0.0, 1.0))
    ang_vis = np.where(valid, np.clip(angle / 30.0, 0.0, 1.0), 0.0)
    panels = [
        ("albedo (sRGB)", linear_to_srgb(scene.albedo)),
        ("normal", np.where(m[..., None], scene.normal * 0.5 + 0.5, 0.0)),
        (f"depth {dmin:.2f}-{dmax:.2f} m", depth_vis),
        ("roughness", scene.roughness),
        ("specular", scene.specular),
        ("mask", m.astype(np.float32)),
        ("Lambert preview", shaded),
        ("|n - n(depth)| (0-30 deg)", ang_vis),
    ]
    h, w = m.shape
    cols, rows = 4, 2
    sheet = Image.new("RGB", (cols * w, rows * (h + 18)), (40, 40, 40))
    draw = ImageDraw.Draw(sheet)
    for k, (title, img) in enumerate(panels):
        img = np.asarray(img, dtype=np.float32)
        if img.ndim == 2:
            img = np.repeat(img[..., None], 3, axis=-1)
        tile = Image.fromarray((np.clip(img, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8))
        r, c = divmod(k, cols)
        sheet.paste(tile, (c * w, r * (h + 18) + 18))
        draw.text((c * w + 4, r * (h + 18) + 3), title, fill=(230, 230, 230))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)
    return path


# ----------------------------------------------------------------------------------------------


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", default=str(ROOT / "assets" / "sample_scene"), help="bundle directory to write")
    ap.add_argument("--size", type=int, default=512, help="image width and height in pixels (default 512)")
    ap.add_argument("--distance", type=float, default=4.0, help="depth of the body's centre in metres (default 4)")
    ap.add_argument("--turn", type=float, default=15.0, help="turn of the body about the vertical, degrees (default 15)")
    ap.add_argument("--fill", type=float, default=0.9, help="fraction of the image height the body spans (default 0.9)")
    ap.add_argument("--sheet", default="out/sample_scene_sheet.png", help="contact sheet PNG of the maps ('' for none)")
    args = ap.parse_args(argv)

    cam = Camera(args.size, args.size, distance=args.distance)
    verts, faces, fields, heads, rest = build_body()
    log(f"posed body with eyeballs: {len(verts)} vertices, {len(faces)} triangles, height {np.ptp(verts[:, 2]):.3f} m")
    verts = dress(verts, faces, fields, heads, rest)
    log("dressed: cloth smoothed and given thickness")

    pos, rot, scale = place_in_camera(verts, cam, args.distance, args.turn, args.fill)
    nrm = vertex_normals(pos, faces)
    log(f"placed in the camera: scale {scale:.3f} (same image as a real-size body at "
        f"{args.distance / scale:.2f} m), depth {-pos[:, 2].max():.3f}-{-pos[:, 2].min():.3f} m, turned {args.turn:g} deg")

    depth, normal, mask, attrs = rasterize(cam, pos, nrm, fields, faces)
    rows, cols = np.nonzero(mask)
    log(f"rasterized {args.size}x{args.size}: {int(mask.sum())} pixels in the mask, rows {rows.min()}-{rows.max()}, "
        f"columns {cols.min()}-{cols.max()}, depth {depth[mask].min():.3f}-{depth[mask].max():.3f} m")

    err = ray_cast_check(cam, pos, faces, depth, mask)
    log(f"depth map vs ray casting through 200 pixel centres: largest difference {err * 1000:.3f} mm")
    if not err < 1e-3:
        print("error: the depth map disagrees with Camera.unproject's rays", file=sys.stderr)
        return 1

    albedo, spec, rough, regions = make_materials(attrs, mask, heads, rest)
    total = max(int(mask.sum()), 1)
    log("materials: " + ", ".join(f"{k} {100.0 * v.sum() / total:.2g} %" for k, v in regions.items())
        + f"; albedo {albedo[mask].min():.3f}-{albedo[mask].max():.3f}")

    scene = Scene(albedo=albedo, specular=spec, roughness=rough, normal=normal, depth=depth.astype(np.float32),
                  mask=mask, camera=cam).validate()
    out = save_scene(scene, args.out)
    size = sum(f.stat().st_size for f in Path(out).iterdir() if f.is_file())
    log(f"wrote {out} ({size / 1e6:.2f} MB): " + ", ".join(sorted(f.name for f in Path(out).iterdir())))

    # verification: load it back (validates), normals against the depth geometry
    loaded = load_scene(out)
    err = max(float(np.abs(loaded.depth - scene.depth).max()), float(np.abs(loaded.normal - scene.normal).max()))
    assert np.array_equal(loaded.mask, scene.mask), "mask changed on the round trip"
    assert err < 1e-5, f"depth/normal changed on the round trip by {err}"
    ang, valid = depth_normal_angle(loaded)
    med = float(np.median(ang[valid]))
    p90 = float(np.percentile(ang[valid], 90))
    facing = float((loaded.normal[loaded.mask][:, 2] > 0.0).mean())
    log(f"loaded back and validated; normals vs depth-map normals over {int(valid.sum())} pixels: "
        f"median {med:.2f} deg, 90th percentile {p90:.2f} deg; n.z > 0 on {100.0 * facing:.1f} % of the mask")
    if med > 10.0:
        print(f"error: the normals disagree with the depth map (median {med:.2f} deg > 10 deg)", file=sys.stderr)
        return 1
    if args.sheet:
        log(f"contact sheet: {contact_sheet(loaded, ang, valid, args.sheet)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
