"""Scene bundles: round trip, and every validation error names the file and the problem."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from viewer.errors import InputError
from viewer.files.imageio import read_exr, write_exr, write_png
from viewer.lab.scenes import plane_and_box
from viewer.resources import sample_scene_dir
from viewer.scene.bundle import load_scene, save_scene
from viewer.scene.depth_mesh import depth_mesh


@pytest.fixture
def bundle(tmp_path):
    sc = plane_and_box(24)
    sc.mask[:3] = False
    sc.validate()
    return save_scene(sc, tmp_path / "scene"), sc


def test_round_trip(bundle):
    path, sc = bundle
    back = load_scene(path)
    np.testing.assert_allclose(back.depth, sc.depth)
    np.testing.assert_allclose(back.normal, sc.normal, atol=1e-6)
    np.testing.assert_allclose(back.albedo, sc.albedo, atol=1e-3)
    assert (back.mask == sc.mask).all()
    assert back.camera == sc.camera


def test_sample_scene_loads():
    sc = load_scene(sample_scene_dir())
    assert sc.mask.mean() > 0.05 and sc.width == sc.height == 512
    assert sc.has_specular


def corrupt(path, name, fn):
    arr = read_exr(path / name)
    write_exr(path / name, fn(arr))


@pytest.mark.parametrize(
    "name, fn, message",
    [
        ("normal.exr", lambda a: a * 2.0, "not unit length"),
        ("albedo.exr", lambda a: a + 1.5, "[0, 1]"),
        ("roughness.exr", lambda a: a - 2.0, "[0, 1]"),
        ("depth.exr", lambda a: np.where(np.arange(a.size).reshape(a.shape) == 400, np.nan, a), "NaN or Inf"),
        ("depth.exr", lambda a: -a, "> 0"),
        ("specular.exr", lambda a: a[:10], "does not match"),
    ],
)
def test_bad_maps_are_named(bundle, name, fn, message):
    path, _ = bundle
    corrupt(path, name, fn)
    with pytest.raises(InputError) as err:
        load_scene(path)
    assert name in str(err.value) and message in str(err.value)


def test_empty_mask_and_missing_files(bundle):
    path, _ = bundle
    write_png(path / "mask.png", np.zeros((24, 24), np.float32))
    with pytest.raises(InputError, match="mask.png.*empty"):
        load_scene(path)
    (path / "depth.exr").unlink()
    with pytest.raises(InputError, match="depth.exr: file not found"):
        load_scene(path)
    (path / "scene.json").write_text("{nope")
    with pytest.raises(InputError, match="scene.json: not a scene bundle description: invalid JSON"):
        load_scene(path)
    with pytest.raises(InputError, match="not found"):
        load_scene(path / "nowhere")


def test_wrong_format_and_resolution(bundle):
    path, _ = bundle
    meta = json.loads((path / "scene.json").read_text())
    meta["camera"]["width"] = 99
    (path / "scene.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="camera resolution"):
        load_scene(path)
    meta["format"] = "other"
    (path / "scene.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="not a scene bundle"):
        load_scene(path)


def test_nan_outside_mask_is_ignored(bundle):
    path, sc = bundle
    corrupt(path, "normal.exr", lambda a: np.where(sc.mask[..., None], a, np.nan))
    back = load_scene(path)
    assert np.isfinite(back.normal).all()


def test_depth_mesh_drops_gaps():
    sc = plane_and_box(200)  # pixel footprint 1.4 cm: the 0.4 m cliff is far steeper than GAP_SLOPE
    mesh = depth_mesh(sc)
    z = -mesh.vertices[mesh.triangles][..., 2]
    assert (z.max(axis=1) - z.min(axis=1)).max() < 0.05  # no triangle bridges the 0.4 m cliff
    full = 2 * 199 * 199
    assert full * 0.9 < mesh.n_triangles < full  # only the triangles along the box's outline go
    coarse = depth_mesh(sc, step=4)
    assert coarse.n_triangles < mesh.n_triangles / 10


def test_one_pixel_mask_scene():
    sc = plane_and_box(16)
    sc.mask[:] = False
    sc.mask[8, 8] = True
    sc.validate()
    assert depth_mesh(sc).n_triangles == 0


@pytest.mark.parametrize("edit, message", [
    (lambda m: [1, 2], "JSON object"),
    (lambda m: {**m, "maps": ["albedo.exr"]}, "maps must be"),
    (lambda m: {**m, "version": "abc"}, "version must be an integer"),
    (lambda m: {**m, "camera": {**m["camera"], "focal_mm": 0}}, "focal_mm must be a number in"),
    (lambda m: {**m, "camera": {**m["camera"], "focal_mm": float("nan")}}, "focal_mm must be a number in"),
    (lambda m: {**m, "camera": {**m["camera"], "model": "orthographic"}}, "perspective"),
])
def test_malformed_scene_json_is_named(bundle, edit, message):
    path, _ = bundle
    meta = json.loads((path / "scene.json").read_text())
    (path / "scene.json").write_text(json.dumps(edit(meta)))
    with pytest.raises(InputError) as err:
        load_scene(path)
    assert "scene.json" in str(err.value) and message in str(err.value)


def test_implausible_depth_is_refused(bundle):
    path, _ = bundle
    corrupt(path, "depth.exr", lambda a: np.where(np.arange(a.size).reshape(a.shape) == 300, 1e20, a))
    with pytest.raises(InputError, match="depth.exr.*implausible"):
        load_scene(path)


def test_a_bundle_is_a_closed_box_no_file_is_read_through_a_link(tmp_path):
    """Every file a bundle is read from, listed or default-named, scene.json and the optional and frame
    files included: a symbolic link to a file outside it is refused in one line naming the file."""
    import shutil

    from viewer.scene.bundle import FRAME_FILES, MAP_FILES, OPTIONAL_FILES, FrameLayer

    base = load_scene(sample_scene_dir())
    h, w = base.height, base.width
    framed = replace(base, frame=FrameLayer(albedo=np.full((h, w, 3), 0.5, np.float32), alpha=base.mask.astype(np.float32),
                                            photo=np.full((h, w, 3), 0.4, np.float32)))
    source = save_scene(framed, tmp_path / "source")
    write_png(source / OPTIONAL_FILES["photo"], np.full((h, w, 3), 0.4, np.float32))  # the optional photo, default-named
    names = ["scene.json", *MAP_FILES.values(), *FRAME_FILES.values(), OPTIONAL_FILES["photo"]]
    assert all((source / n).is_file() for n in names)
    outside = tmp_path / "secret"
    outside.mkdir()
    for name in names:
        bundle = tmp_path / f"b_{name}"
        shutil.copytree(source, bundle)
        (outside / name).write_bytes((bundle / name).read_bytes())  # a valid file, but not the bundle's
        (bundle / name).unlink()
        (bundle / name).symlink_to(outside / name)
        with pytest.raises(InputError, match="symbolic link") as info:
            load_scene(bundle)
        assert name in str(info.value) and "\n" not in str(info.value)
    assert json.loads((source / "scene.json").read_text())["format"] == "relight-scene"
    load_scene(source)  # the untouched bundle loads


def test_a_stage_checks_the_maps_it_replaced():
    """``validate(only=...)``: a stage that replaced some maps of a scene checked whole checks those:
    a NaN or an out-of-range value in them is refused, naming the map; a map it did not replace is
    not read again; a map name that is not one is a programming error."""
    sc = plane_and_box(24)
    sc.mask[:3] = False
    sc = sc.validate()
    bad = sc.specular.copy()
    bad[sc.mask] = np.nan
    with pytest.raises(InputError, match="specular.exr: .* NaN or Inf"):
        replace(sc, specular=bad).validate(only=frozenset({"specular"}))
    far = sc.depth.copy()
    far[sc.mask] = 1e9
    with pytest.raises(InputError, match="depth.* implausible"):
        replace(sc, depth=far).validate(only=frozenset({"normal", "depth"}))
    zeroed = replace(sc, specular=np.where(sc.mask, 0.25, 7.0).astype(np.float32)).validate(only=frozenset({"specular"}))
    assert zeroed.specular[~sc.mask].max() == 0.0 and zeroed.specular[sc.mask].min() == 0.25
    assert zeroed.normal is sc.normal  # not read again
    with pytest.raises(ValueError, match="no such maps"):
        sc.validate(only=frozenset({"specularity"}))
