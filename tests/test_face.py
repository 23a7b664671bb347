"""The face fitted at its own resolution (viewer.photo.face): MediaPipe's face landmarks on real files
(renders of held-out synthetic people written by `relight dataset make`, with their masks as alpha,
and the bundled photo), rasterized into depth and normals and blended into a scene's maps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from viewer.photo import face
from viewer.photo.frames import read_photo
from viewer.scene.bundle import Scene
from viewer.scene.camera import Camera

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"


def _person(name):
    """(RGB uint8, alpha float in [0, 1]) of tests/data/person_<name>.png."""
    rgba = np.asarray(Image.open(DATA / f"person_{name}.png").convert("RGBA"))
    return np.ascontiguousarray(rgba[..., :3]), rgba[..., 3].astype(np.float32) / 255.0


def _scene(alpha, depth=4.0):
    """A plain scene over the person's mask: normals facing the camera, depth ``depth``."""
    h, w = alpha.shape
    mask = alpha > 0.5
    normal = np.zeros((h, w, 3), np.float32)
    normal[mask] = (0.0, 0.0, 1.0)
    return Scene(albedo=np.where(mask[..., None], np.float32(0.5), np.zeros(3, np.float32)).astype(np.float32),
                 specular=np.full((h, w), 0.5, np.float32),
                 roughness=np.full((h, w), 0.5, np.float32), normal=normal,
                 depth=np.where(mask, depth, 4.0).astype(np.float32), mask=mask, camera=Camera(w, h)).validate()


def _fitted_normal(name, mirror=False):
    """The mean normal of the face fitted to person_<name>; ``mirror``: of its landmarks mirrored
    left to right (the detector itself is not mirror-symmetric)."""
    rgb, alpha = _person(name)
    faces = face.find_faces(rgb, alpha)
    assert len(faces) == 1
    fit = faces[0]
    if mirror:
        w = alpha.shape[1]
        fit = face.FaceLandmarks(fit.points * [-1, 1, 1] + [w, 0, 0], fit.box, fit.score)
        alpha = np.ascontiguousarray(alpha[:, ::-1])
    surface = face.face_surface(fit, 1.0, alpha.shape, alpha > 0.5)
    return surface.normal[surface.weight > 0.5].mean(axis=0)


def test_the_mesh_is_the_face_models_triangles_wound_one_way_and_closed():
    """The tesselation's 3-cliques less the two at the nostrils that are not faces: the canonical
    mesh's 852 triangles, each edge run once each way by its two triangles; closed over the eyes
    and the mouth, one boundary loop is left (the face's outline) and the whole faces the camera."""
    tris = face.triangles()
    assert tris.shape == (852, 3) and tris.min() == 0 and tris.max() == 467
    directed = [(int(t[k]), int(t[(k + 1) % 3])) for t in tris for k in range(3)]
    assert len(set(directed)) == len(directed)  # no edge runs the same way twice
    rgb, alpha = _person("front")
    points, closed = face.face_mesh(face.find_faces(rgb, alpha)[0].points)
    assert points.shape == (471, 3) and closed.shape == (852 + 16 + 16 + 20, 3)
    directed = {(int(t[k]), int(t[(k + 1) % 3])) for t in closed for k in range(3)}
    boundary = [(u, v) for u, v in directed if (v, u) not in directed]
    assert len(boundary) == 36  # the face oval alone
    a, b, c = points[closed[:, 0]], points[closed[:, 1]], points[closed[:, 2]]
    facing = np.cross(b - a, c - a)[:, 2] < 0  # MediaPipe's z points away from the camera
    assert facing.mean() > 0.9


def test_depth_integrated_from_a_spheres_normals_is_the_sphere():
    """integrate_depth over a disc of a sphere's cap, held along its rim to a guess that has the
    sphere's level but none of its relief (a blurred, flattened depth, as the networks' is), gives
    the sphere's relief back (within a tenth) and leaves every pixel off the disc as it was."""
    import cv2

    h = w = 96
    focal, distance, radius = 800.0, 4.0, 0.2  # metres: a 20 cm ball at 4 m
    yy, xx = np.mgrid[:h, :w]
    mpp = distance / focal
    x, y = (xx + 0.5 - w / 2) * mpp, -(yy + 0.5 - h / 2) * mpp
    r2 = x ** 2 + y ** 2
    ball = r2 < radius ** 2
    z = np.sqrt(np.maximum(radius ** 2 - r2, 0))
    depth = np.where(ball, distance - z, distance).astype(np.float32)
    normal = np.where(ball[..., None], np.stack([x, y, z], -1) / radius, [0, 0, 1]).astype(np.float32)
    region = r2 < (0.8 * radius) ** 2
    guess = cv2.GaussianBlur(depth, (0, 0), 12).astype(np.float32)  # the level, not the relief
    inside = cv2.distanceTransform(region.astype(np.uint8), cv2.DIST_L2, 5)
    hold = np.clip(1.0 - inside / 6.0, 0.0, 1.0).astype(np.float32)  # a ramp of 6 pixels from the rim
    out = face.integrate_depth(normal, guess, region, hold, focal)
    assert np.isfinite(out).all() and (out[~region] == guess[~region]).all()
    relief = float(depth[region].max() - depth[region].min())
    shape_error = (out - depth)[region] - np.median((out - depth)[region])
    assert np.abs(shape_error).max() < 0.1 * relief
    assert float(out[region].max() - out[region].min()) == pytest.approx(relief, rel=0.1)


def test_a_front_face_is_fitted_and_faces_the_camera():
    rgb, alpha = _person("front")
    faces = face.find_faces(rgb, alpha)
    assert len(faces) == 1 and faces[0].points.shape == (468, 3) and faces[0].score > 0.5
    left, top, width, height = faces[0].box
    assert 25 < faces[0].width < 60 and 60 < left + width / 2 < 130  # the head of the 192-pixel crop
    n = _fitted_normal("front")
    assert abs(n[0]) < 0.03 and n[2] > 0.8  # the face as a whole looks at the camera


def test_the_face_normals_point_up_on_the_forehead_and_down_under_the_chin():
    """Camera space has y up while image rows go down: the fitted forehead faces up, the chin's
    underside and the nose's tip down (MediaPipe landmarks 10: forehead, 152: chin, 1: nose tip)."""
    rgb, alpha = _person("front")
    fit = face.find_faces(rgb, alpha)[0]
    surface = face.face_surface(fit, 1.0, alpha.shape, alpha > 0.5)
    def normal_at(i, dy=0):
        x, y = fit.points[i, :2]
        return surface.normal[int(y) + dy, int(x)]
    assert normal_at(10, 2)[1] > 0.1 and normal_at(152, -2)[1] < -0.3 and normal_at(1)[2] > 0.3


def test_a_turned_face_leans_its_normals_the_way_it_turns():
    """person_turned looks to the image's left (three quarters): its fitted normals lean to -x, and
    those of its landmarks mirrored to +x by as much (the axes' signs are right)."""
    n, mirrored = _fitted_normal("turned"), _fitted_normal("turned", mirror=True)
    assert n[0] < -0.04 and mirrored[0] > 0.04
    assert abs(n[0] + mirrored[0]) < 0.03


def test_a_profile_face_the_detector_misses_leaves_the_maps():
    rgb, alpha = _person("profile")
    faces = face.find_faces(rgb, alpha)
    assert faces == []
    scene = _scene(alpha)
    out, record, _ = face.with_face(scene, faces, 1.0)
    assert out is scene and record == {"faces_found": 0, "fitted": None}


def test_no_face_in_the_photo():
    """The bundled photo's legs and feet: a person, no face."""
    photo = read_photo(ROOT / "assets" / "photos" / "underpass.jpg", [])
    legs = np.ascontiguousarray(photo[photo.shape[0] // 2:])
    assert face.find_faces(legs, np.ones(legs.shape[:2], np.float32)) == []


def test_of_several_faces_only_the_persons_are_kept():
    """Two people side by side: with both in the matte both faces are found (largest first); with
    one person's matte, only that person's face."""
    (a, alpha_a), (b, alpha_b) = _person("front"), _person("turned")
    both = np.ascontiguousarray(np.concatenate([a, b], axis=1))
    two = face.find_faces(both, np.concatenate([alpha_a, alpha_b], axis=1))
    assert len(two) == 2 and two[0].width >= two[1].width
    one = face.find_faces(both, np.concatenate([np.zeros_like(alpha_a), alpha_b], axis=1))
    assert len(one) == 1 and one[0].box[0] > a.shape[1]


def test_the_blend_stays_bounded_and_local():
    """The fitted face changes normals and depth only on the face, keeps normals unit and depth
    finite and within a head's depth of the maps, and ramps in from the face's outline."""
    rgb, alpha = _person("front")
    scene = _scene(alpha)
    out, record, _ = face.with_face(scene, face.find_faces(rgb, alpha), 1.0)
    assert record["faces_found"] == 1 and record["fitted"]["work_pixels"] > 300
    changed = (np.abs(out.depth - scene.depth) > 1e-6) | (np.abs(out.normal - scene.normal).sum(-1) > 1e-6)
    assert changed.any() and changed.sum() <= record["fitted"]["work_pixels"]
    m = out.mask
    assert np.allclose(np.linalg.norm(out.normal[m], axis=-1), 1.0, atol=1e-4)
    assert np.isfinite(out.depth).all() and np.abs(out.depth - scene.depth).max() < 0.15
    nose = face.find_faces(rgb, alpha)[0].points[1]  # landmark 1: the tip of the nose
    assert out.depth[int(nose[1]), int(nose[0])] < 4.0  # in front of the face's median
    surface = face.face_surface(face.find_faces(rgb, alpha)[0], 1.0, alpha.shape, m)
    assert surface.weight.min() >= 0.0 and surface.weight.max() == pytest.approx(1.0)
    edge = surface.region & ~np.pad(surface.region, 1)[2:, 1:-1]  # the outline's lowest row of each column
    assert surface.weight[edge].max() < 0.5


def test_a_face_too_small_for_the_work_frame_is_left_out():
    rgb, alpha = _person("front")
    faces = face.find_faces(rgb, alpha)
    scene = _scene(alpha)
    small = face.MIN_FACE_WORK_PX / faces[0].width * 0.9  # the work frame at this scale of the photo
    assert face.face_surface(faces[0], small, alpha.shape, scene.mask) is None
    out, record, _ = face.with_face(scene, faces, small)
    assert out is scene and "skipped" in record


def test_the_face_counts_its_share_in_the_fit_of_the_photos_lights(ctx):
    """A sphere whose 'face' (a patch on its right) is lit from the right and the rest from the
    left: weighted as inference weighs a face, the fitted lights explain the patch better than
    unweighted, and the weights give the patch ``FIT_SHARE`` of the fit."""
    from viewer.gl import Engine, EngineOptions
    from viewer.lab.scenes import sphere
    from viewer.photo.own_lighting import fit_photo_lights
    from viewer.scene.area_lights import AreaLights

    scene = sphere(64, albedo=0.6, specular=0.0)
    h, w = scene.mask.shape
    yy, xx = np.mgrid[:h, :w]
    patch = scene.mask & (xx > 0.62 * w) & (np.abs(yy - h / 2) < 0.12 * h)
    engine = Engine(ctx, scene, EngineOptions())
    try:
        images = []
        for x in (-0.8, 0.8):
            direction = np.array([[x, 0.3, 0.5]], np.float32)
            engine.set_lights(AreaLights(direction / np.linalg.norm(direction), np.full(1, 2.0, np.float32),
                                         np.ones((1, 3), np.float32)))
            images.append(engine.render().output.read_work_hdr()[..., :3].copy())
        target = np.where(patch[..., None], images[1], images[0]).astype(np.float32)
        ramp = np.clip((np.minimum(xx - 0.62 * w, 0.12 * h - np.abs(yy - h / 2)) / 3.0), 0.0, 1.0) * patch  # 0 at its edge
        surface = face.FaceSurface(scene.normal, ramp.astype(np.float32), patch)
        weight = face.light_fit_weight(surface, scene.mask)
        assert weight[ramp > 0].sum() / weight[scene.mask].sum() == pytest.approx(face.FIT_SHARE, rel=1e-3)
        assert weight.min() >= 1.0 and weight[~patch].max() == 1.0
        errors = []
        for wt in (None, weight):
            lights, _ = fit_photo_lights(engine, target, scene.mask, weight=wt)
            engine.set_lights(lights)
            fitted = engine.render().output.read_work_hdr()[..., :3]
            errors.append(float(np.abs(fitted[patch] - target[patch]).mean() / target[patch].mean()))
    finally:
        engine.release()
    assert errors[1] < 0.7 * errors[0]


def test_a_face_too_dark_for_the_detector_is_found_equalized():
    """The front render exposed 1/20 as bright (an underexposed photo): the detector finds nothing
    in it as it is; the retry with its lightness equalized finds the face, at the same place."""
    rgb, alpha = _person("front")
    dark = (rgb.astype(np.float32) * 0.05).astype(np.uint8)
    assert face._faces(dark, alpha) == []
    found, reference = face.find_faces(dark, alpha), face.find_faces(rgb, alpha)
    assert len(found) == 1
    assert np.abs(found[0].points[:, :2] - reference[0].points[:, :2]).mean() < 2.0  # pixels


def test_a_clips_face_landmarks_are_smoothed_and_followed():
    """The One Euro filter of a clip's face: a still face's jitter (0.5 px) falls to under half, a
    face moving 10 % of its width a frame is followed within 2.5 % of its width, and another
    face (a jump) starts the filter afresh."""
    from viewer.photo.face import FaceLandmarks
    from viewer.photo.face_track import FaceTrack

    rng = np.random.default_rng(1)
    base = np.stack([rng.uniform(0, 100, 468), rng.uniform(0, 120, 468), rng.uniform(-10, 10, 468)], -1)
    track = FaceTrack()

    def face(points):
        return FaceLandmarks(points, (0.0, 0.0, 100.0, 120.0), 0.9)

    still = [track.smooth([face(base + rng.normal(0, 0.5, base.shape))])[0].points for _ in range(60)]
    assert np.std(np.array(still[20:]) - base, axis=0).mean() < 0.5 / 2
    moving = [track.smooth([face(base + [10.0 * k, 0, 0])])[0].points for k in range(1, 30)]
    assert np.abs(moving[-1] - (base + [290.0, 0, 0])).max() < 2.5
    jumped = track.smooth([face(base + [1000.0, 0, 0])])[0].points
    np.testing.assert_array_equal(jumped, base + [1000.0, 0, 0])
    assert track.smooth([]) == [] and track.filter.value is None
