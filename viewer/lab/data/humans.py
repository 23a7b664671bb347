"""Synthetic people: anny bodies (shape and pose), clothing thickness, placement in the project's
camera, and G-buffers by rasterization (moderngl, headless EGL).

anny (``anny==0.6.2``; code Apache-2.0, body data from MakeHuman, CC0) gives a posable, skinned body
with 13,718 vertices; the ``notoes`` topology (feet without toes, for shoes) leaves the eye sockets
empty, so eyeballs are added. Axes: anny's (x = the body's left, y = its back, z = up) until
:func:`place_in_camera` turns the body into camera space.
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from viewer.lab.data.geometry import icosphere, mesh_edges, neighbour_mean, signed_volume, vertex_normals
from viewer.lab.data.materials import SAMPLE_OUTFIT, Outfit, classify
from viewer.scene.camera import Camera

ARM_BONES = ("upperarm", "lowerarm", "wrist", "finger", "metacarpal")
HEAD_BONES = ("neck01", "neck02", "neck03", "head", "eye.L", "eye.R")
EYE_BONES = ("eye.L", "eye.R")
FOOT_BONES = ("foot", "toe")


@lru_cache(maxsize=1)
def body_model():
    """The anny body model (built once per process; the first construction on a machine takes one
    to two minutes and builds a ~1.7 GB cache in ``ANNY_CACHE_DIR``, default ~/.cache/anny)."""
    os.environ.setdefault("ANNY_CACHE_DIR", str(Path.home() / ".cache" / "anny"))
    import anny

    return anny.Anny(topology="notoes", local_changes="default")  # feet without toes: shoes


def triangles(model) -> np.ndarray:
    """(F, 3) int64: the anny model's faces as triangles (its quads split when it has quads)."""
    faces = model.faces.numpy().astype(np.int64)
    return faces if faces.shape[1] == 3 else model.get_triangular_faces().numpy().astype(np.int64)


def build_body(phenotype: dict, pose: dict):
    """Pose the anny body: ``phenotype`` (anny's phenotype values in [0, 1]) and ``pose`` (bone ->
    rotation vector, radians, anny's local axes). Returns posed and rest vertices (anny axes,
    metres), triangles, the per-vertex fields the materials are made from, the rest-pose bone
    heads, and the rest vertices."""
    import roma
    import torch

    model = body_model()
    labels = list(model.bone_labels)

    dtype = model.dtype
    pose_t = torch.eye(4, dtype=dtype).repeat(1, len(labels), 1, 1)
    for bone, rotvec in pose.items():
        pose_t[0, labels.index(bone), :3, :3] = roma.rotvec_to_rotmat(torch.tensor(rotvec, dtype=dtype))
    with torch.no_grad():
        out = model(pose_parameters=pose_t, phenotype_kwargs=phenotype)
    verts = out["vertices"][0].numpy().astype(np.float64)
    rest = out["rest_vertices"][0].numpy().astype(np.float64)
    heads = {b: out["rest_bone_heads"][0, i].numpy().astype(np.float64) for i, b in enumerate(labels)}
    faces = triangles(model)

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


ANNY_TO_CAMERA = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # facing the camera: front (-y) -> +z


def placement(verts: np.ndarray, cam: Camera, distance: float, turn_deg: float, fill: float):
    """The similarity that puts a body in the camera: (rotation r, scale s, centre c, translation t),
    camera-space points ``s * (verts @ r.T - c) + t``. Anny axes (x left, -y front, z up) -> camera space (x right,
    y up, z to the camera) with the body facing the camera, turned ``turn_deg`` about the vertical,
    its bounding-box centre at depth ``distance`` and scaled so that its projection spans ``fill``
    of the image height, centred."""
    a = np.radians(turn_deg)
    rot_y = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    r = rot_y @ ANNY_TO_CAMERA
    b = verts @ r.T
    centre = 0.5 * (b.min(axis=0) + b.max(axis=0))
    b = b - centre
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
    return r, s, centre, t


def place_in_camera(verts: np.ndarray, cam: Camera, distance: float, turn_deg: float, fill: float):
    """``verts`` placed by :func:`placement`; returns (camera-space vertices, rotation, scale)."""
    r, s, centre, t = placement(verts, cam, distance, turn_deg, fill)
    return s * (verts @ r.T - centre) + t, r, s


VERTEX_SHADER = """
#version 410 core
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
#version 410 core
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

    ctx = moderngl.create_standalone_context(backend="egl", require=410)
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


# how far each region stands off the skin (metres, before scaling), and whether the body's shape
# under it is smoothed (cloth hides navel, nipples and the like)
STANDOFF = {"shirt": 0.012, "trousers": 0.016, "belt": 0.018, "shoe": 0.010, "sole": 0.012,
            "strap": 0.016, "watch": 0.008, "necklace": 0.003}  # hair: the outfit's hair_volume; cap: above the hair
CAP = 0.008  # how far a knit cap stands off the hair
CLOTH = ("shirt", "trousers", "belt", "shoe", "sole", "strap", "watch")


def dress(verts: np.ndarray, faces: np.ndarray, fields: np.ndarray, heads: dict, rest: np.ndarray,
          outfit: Outfit = SAMPLE_OUTFIT) -> np.ndarray:
    """Give clothes and hair some thickness: smooth the body under the cloth and long hair (Taubin
    smoothing, which does not shrink, along the normals only) and push each region off the skin
    along the normal by its STANDOFF (hair by the outfit's hair volume), with short ramps at the
    hems."""
    n = len(verts)
    edges = mesh_edges(faces)
    regions = classify(fields, heads, rest, outfit)
    cloth = np.zeros(n)
    off = np.zeros(n)
    for name in CLOTH:
        cloth[regions[name]] = 1.0
    for name, d in STANDOFF.items():
        off[regions[name]] = d
    # hair stands off by the person's hair volume; long hair falling down the back lies over the top
    off[regions["hair"]] = outfit.hair_volume + np.where(fields[regions["hair"], 5] > 0.5, 0.0, STANDOFF["shirt"])
    cloth[regions["hair"] & (fields[:, 5] <= 0.5)] = 1.0
    off[regions["cap"]] = outfit.hair_volume + CAP
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


def fold(pos: np.ndarray, faces: np.ndarray, normals: np.ndarray, fields: np.ndarray, heads: dict, rest: np.ndarray,
         outfit: Outfit, scale: float, seed: int):
    """Cloth folds and hair strands as a displacement along the normals of a finely subdivided
    mesh: garments get ridges across the limbs and the body (noise compressed along the vertical of
    the rest pose) with some crumpling, hair gets grooves that run down it. ``scale`` turns metres
    into the mesh's units. Returns the displaced positions and their normals: the smooth normals
    plus the change the displacement makes to the faceted ones, so the base mesh's facets do not
    show."""
    from viewer.lab.data.materials import fbm, value_noise

    if outfit.folds <= 0.0:
        return pos, normals
    regions = classify(fields, heads, rest, outfit)
    p = fields[:, 0:3]
    garment = np.zeros(len(pos))
    for name in ("shirt", "trousers"):
        garment[regions[name]] = 1.0
    ridges = 0.7 * fbm(p * np.array([1.0, 1.0, 3.0]), 0.09, seed, octaves=3) + 0.3 * fbm(p, 0.03, seed + 5, octaves=2)
    strands = value_noise(p * np.array([1.0, 1.0, 0.12]), 0.005, seed + 9)
    d = outfit.folds * (garment * ridges + 0.5 * regions["hair"] * strands)
    moved = pos + (scale * d)[:, None] * normals
    n = normals + vertex_normals(moved, faces) - vertex_normals(pos, faces)
    return moved, n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


# ----------------------------------------------------------------------------------------------
# Random people
# ----------------------------------------------------------------------------------------------

POSE_STYLES = ("relaxed", "arms_out", "crossed_legs", "stride", "hands_on_hips", "walking", "arms_raised")
POSE_STYLE_WEIGHTS = (0.25, 0.15, 0.1, 0.1, 0.1, 0.15, 0.15)
RAISE = (-1.9, -0.8)  # about the back axis: anny's rest pose holds the arms ~48 degrees below horizontal


def seat(pose: dict, rng: np.random.Generator) -> dict:
    """``pose`` sitting: thighs forward to about horizontal, knees bent so that the shins are near
    vertical, feet a little apart, the back upright or leaning a little forward; the arms keep their pose. The
    seat itself is not modelled (only the person is in the mask, as in a photo's matte)."""
    u = rng.uniform
    seated = dict(pose)
    spread = u(0.0, 0.1)
    for side, sign in (("L", 1.0), ("R", -1.0)):
        flex = u(1.3, 1.6)
        seated[f"upperleg01.{side}"] = (-flex, -sign * spread, 0.0)
        seated[f"lowerleg01.{side}"] = (flex + u(-0.2, 0.25), 0.0, 0.0)  # the shin near vertical
    seated["spine01"] = (u(-0.25, 0.0), u(-0.04, 0.04), u(-0.1, 0.1))
    return {k: tuple(float(x) for x in v) for k, v in seated.items()}


def sample_phenotype(rng: np.random.Generator) -> dict:
    """anny phenotype values of an adult (anny: gender 0 male .. 1 female; age 2/3 young adult .. 1 old)."""
    return dict(gender=float(rng.uniform(0.0, 1.0)), age=float(rng.uniform(0.6, 0.95)), muscle=float(rng.uniform(0.25, 0.75)),
                weight=float(rng.uniform(0.2, 0.8)), height=float(rng.uniform(0.2, 0.8)),
                proportions=float(rng.uniform(0.2, 0.8)))


def sample_pose(rng: np.random.Generator) -> tuple[str, dict]:
    """A natural standing pose: bone -> rotation vector (radians, anny's world-aligned local axes:
    x = the body's left, y = its back, z = up; about x, negative swings a hanging limb forward;
    about y, positive brings the left arm towards the body and the left leg across). Arms away from
    and against the body, bent elbows, crossed legs, a stride, hands on hips: the poses that cast
    limb-on-body shadows. Walking swings each arm against its leg; arms raised lifts one arm or both
    to between horizontal and overhead."""
    u = rng.uniform
    style = POSE_STYLES[int(rng.choice(len(POSE_STYLES), p=POSE_STYLE_WEIGHTS))]
    pose = {}
    standing = "L" if rng.uniform() < 0.5 else "R"  # the leg carrying the weight (walking: the leg behind)
    free = "R" if standing == "L" else "L"
    fs = 1.0 if free == "L" else -1.0
    raised = {"L", "R"} if u() < 0.4 else {("L", "R")[int(rng.integers(2))]}
    for side, sign in (("L", 1.0), ("R", -1.0)):
        if style == "walking":
            # the arm on the side of the leg in front swings back, the other forward
            swing = u(0.15, 0.45) if side == free else u(-0.5, -0.2)
            pose[f"upperarm01.{side}"] = (swing, sign * u(0.45, 0.7), 0.0)
            pose[f"lowerarm01.{side}"] = (u(0.1, 0.7), 0.0, sign * u(0.0, 0.4))
            continue
        if style == "arms_raised" and side in raised:
            pose[f"upperarm01.{side}"] = (u(-0.4, 0.2), sign * u(*RAISE), 0.0)
            pose[f"lowerarm01.{side}"] = (u(0.0, 1.2), 0.0, sign * u(0.0, 0.5))
            continue
        if style == "hands_on_hips":
            # elbows out to the side, forearms turned in towards the hips (about the back axis)
            pose[f"upperarm01.{side}"] = (u(0.1, 0.3), -sign * u(0.2, 0.35), 0.0)
            pose[f"lowerarm01.{side}"] = (u(-0.1, 0.1), sign * u(1.6, 1.9), 0.0)
            continue
        if style == "arms_out":
            swing, adduct, elbow = u(-0.5, 0.3), u(-0.45, 0.1), u(0.0, 0.9)
        else:
            swing, adduct, elbow = u(-0.35, 0.3), u(0.2, 0.68), u(0.05, 1.0)
        pose[f"upperarm01.{side}"] = (swing, sign * adduct, 0.0)
        pose[f"lowerarm01.{side}"] = (elbow, 0.0, sign * u(0.0, 0.5))
    if style == "crossed_legs":
        pose[f"upperleg01.{free}"] = (u(-0.3, -0.15), fs * u(0.3, 0.42), 0.0)  # forward and across the other
        pose[f"lowerleg01.{free}"] = (u(0.05, 0.3), 0.0, 0.0)
    elif style == "walking":  # mid-step: the free leg forward, the standing leg behind on its toes
        pose[f"upperleg01.{free}"] = (u(-0.45, -0.2), 0.0, 0.0)
        pose[f"lowerleg01.{free}"] = (u(0.05, 0.35), 0.0, 0.0)
        pose[f"upperleg01.{standing}"] = (u(0.1, 0.35), 0.0, 0.0)
        pose[f"lowerleg01.{standing}"] = (u(0.2, 0.6), 0.0, 0.0)
    elif style == "stride":
        pose[f"upperleg01.{free}"] = (u(-0.5, -0.25), -fs * u(0.0, 0.1), 0.0)
        pose[f"lowerleg01.{free}"] = (u(0.1, 0.5), 0.0, 0.0)
        pose[f"upperleg01.{standing}"] = (u(0.1, 0.3), 0.0, 0.0)
    else:
        pose[f"upperleg01.{free}"] = (u(-0.35, 0.0), -fs * u(-0.04, 0.12), 0.0)
        pose[f"lowerleg01.{free}"] = (u(0.0, 0.6), 0.0, 0.0)
        pose[f"upperleg01.{standing}"] = (0.0, (1.0 if standing == "L" else -1.0) * u(-0.06, 0.04), 0.0)
    pose["spine03"] = (u(-0.05, 0.05), u(-0.06, 0.06), u(-0.2, 0.2))
    pose["spine01"] = (u(-0.05, 0.08), u(-0.04, 0.04), u(-0.1, 0.1))
    pose["neck01"] = (u(-0.1, 0.15), 0.0, 0.0)
    pose["head"] = (u(-0.15, 0.2), u(-0.12, 0.12), u(-0.5, 0.5))
    return style, {k: tuple(float(x) for x in v) for k, v in pose.items()}
