"""The lab's body fit (viewer/lab/data/body_fit.py): MediaPipe's landmarks on a real photo, and anny
fitted back to the landmarks of a known posed body."""

from __future__ import annotations

import numpy as np
from conftest import SHARED_DATA

from viewer.lab.data.body_fit import JOINTS, fit_body, landmarks
from viewer.lab.data.body_prior import AVERAGE
from viewer.lab.data.geometry import vertex_normals
from viewer.lab.data.humans import build_body, placement, rasterize
from viewer.scene.camera import Camera


def test_landmarks_of_a_real_photo():
    import imageio.v3 as iio

    photo = iio.imread(SHARED_DATA / "photos" / "unsplash-1507274733827.jpg")[..., :3]
    found = landmarks(photo)
    assert found is not None
    image, visibility, world = found
    assert image.shape == (33, 2) and world.shape == (33, 3) and visibility[[11, 12, 23, 24]].min() > 0.5
    assert image[[11, 12], 1].mean() < image[[23, 24], 1].mean()  # shoulders above hips in the image
    assert world[[11, 12], 1].mean() > world[[23, 24], 1].mean()  # and above them in the world (y up)


def test_anny_fitted_to_a_known_bodys_landmarks_lands_on_it():
    pose = {"upperarm01.L": (-0.4, -0.9, 0.0), "lowerarm01.L": (0.8, 0.0, 0.0), "upperleg01.R": (-0.4, 0.0, 0.0),
            "lowerleg01.R": (0.5, 0.0, 0.0), "upperarm01.R": (0.2, -0.3, 0.0)}
    verts, faces, _, heads, _ = build_body(AVERAGE, pose)
    cam = Camera(256, 256)
    r, s, centre, t = placement(verts, cam, cam.distance, 20.0, 0.85)
    pos = s * (verts @ r.T - centre) + t
    # the landmarks this body would give: its joints projected, and about its hips in metres
    import torch

    from viewer.lab.data.humans import body_model

    model = body_model()
    labels = list(model.bone_labels)
    import roma

    mats = torch.eye(4, dtype=model.dtype).repeat(1, len(labels), 1, 1)
    for bone, rv in pose.items():
        mats[0, labels.index(bone), :3, :3] = roma.rotvec_to_rotmat(torch.tensor(rv, dtype=model.dtype))
    with torch.no_grad():
        bones = model(pose_parameters=mats, phenotype_kwargs=AVERAGE)["bone_poses"][0, :, :3, 3].numpy()
    image, visibility, world = np.zeros((33, 2)), np.zeros(33), np.zeros((33, 3))
    f, (cx, cy) = cam.focal_px, cam.center
    for k, bone in JOINTS.items():
        j = bones[labels.index(bone)]
        c = s * (j @ r.T - centre) + t
        image[k] = (cx + f * c[0] / -c[2], cy - f * c[1] / -c[2])
        world[k] = j @ r.T
        visibility[k] = 1.0
    world -= world[[23, 24]].mean(axis=0)
    fit = fit_body(image, visibility, world, cam)
    assert fit["reprojection_px"] < 3.0
    d_true, _, m_true, _ = rasterize(cam, pos, vertex_normals(pos, faces), np.zeros((len(pos), 8)), faces)
    d_fit, _, m_fit, _ = rasterize(cam, fit["vertices"], vertex_normals(fit["vertices"], fit["faces"]),
                                   np.zeros((len(fit["vertices"]), 8)), fit["faces"])
    assert (m_true & m_fit).sum() / (m_true | m_fit).sum() > 0.75
    both = m_true & m_fit
    diff = (d_fit - d_true)[both]
    flat = d_true[m_true] - np.median(d_true[m_true])
    assert np.abs(diff - np.median(diff)).mean() < 0.5 * np.abs(flat).mean()  # the depth, not only the outline


def test_bench_bodyfit_scores_the_fit_the_prior_and_a_flat_figure(tiny_dataset, tmp_path, capsys):
    import json

    from viewer.cli.main import main

    assert main(["bench", "bodyfit", "--data", str(tiny_dataset[0]), "--limit", "1", "-o", str(tmp_path / "b.json")]) == 0
    result = json.loads((tmp_path / "b.json").read_text())
    s = result["summary"]
    assert s["people"] == 1 and 0 <= s["landmarks_found"] <= 1
    assert 0 < s["depth_l1_cm"]["flat"] < 30 and 0 < s["depth_l1_cm"]["experiment_prior"] < 30
    assert 0.3 < s["iou"]["experiment_prior"] <= 1.0
    assert "flat figure" in capsys.readouterr().out
    assert main(["bench", "bodyfit"]) == 2  # no --data: one line
