"""``relight infer``: a real photo to a scene bundle the engine renders, bad inputs, the bundle cache."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from viewer.cli import main
from viewer.errors import InputError
from viewer.gl import Engine, EngineOptions
from viewer.inference import FILL, cached_bundle, crop, framing, infer, load_networks
from viewer.lights import load_lights
from viewer.scene import load_scene

from conftest import SHARED_DATA

PHOTOS = SHARED_DATA / "photos"


def _person(tmp_path, h=96, w=64, mode="RGB"):
    """A synthetic photo (a lit ellipse on a gradient) and its mask, written as PNGs."""
    yy, xx = np.mgrid[:h, :w]
    inside = ((yy - h / 2) / (0.4 * h)) ** 2 + ((xx - w / 2) / (0.15 * w)) ** 2 < 1
    img = np.stack([xx / w, yy / h, np.full((h, w), 0.5)], -1)
    img[inside] = [0.8, 0.6, 0.5]
    photo, mask = tmp_path / "photo.png", tmp_path / "mask.png"
    u8 = (img * 255).astype(np.uint8)
    Image.fromarray(u8[..., 0] if mode == "L" else u8).save(photo)
    Image.fromarray((inside * 255).astype(np.uint8)).save(mask)
    return photo, mask, inside


def test_real_photo_becomes_a_bundle_the_engine_renders(tiny_networks, ctx, tmp_path, capsys):
    photo, mask = PHOTOS / "unsplash-1535323700481.jpg", PHOTOS / "unsplash-1535323700481.mask.png"  # landscape, RGB mask
    out = tmp_path / "bundle"
    assert main(["infer", str(photo), "--mask", str(mask), "-o", str(out), "--size", "128",
                 "--networks", str(tiny_networks)]) == 0
    assert "wrote scene bundle" in capsys.readouterr().out
    scene = load_scene(out)
    assert scene.width == scene.height == 128 and scene.photo is not None
    rows = np.flatnonzero(scene.mask.any(axis=1))
    assert abs((rows[-1] - rows[0] + 1) / 128 - FILL) < 0.03  # framed as the training people are
    inside = scene.mask
    assert np.all(np.isfinite(scene.depth)) and np.all(scene.depth[inside] > 0)
    assert np.allclose(np.linalg.norm(scene.normal[inside], axis=-1), 1, atol=1e-3)
    lights = load_lights(out / "lights.json")
    assert len(lights) == 16 and np.all(np.isfinite(lights.intensity)) and np.all(lights.intensity >= 0)
    record = json.loads((out / "inference.json").read_text())
    assert record["photo_size"] == [1950, 1302] and record["seconds_total"] > 0
    engine = Engine(ctx, scene, EngineOptions(shadow_resolution=256))
    try:
        engine.set_lights(lights)
        hdr = engine.render().read_hdr()
    finally:
        engine.release()
    assert np.all(np.isfinite(hdr)) and hdr[..., :3][inside].mean() > 0


def test_framing_pads_with_the_photo_edge():
    mask = np.zeros((100, 40), bool)
    mask[10:90, 15:25] = True  # 80 px tall: the square is 80 / FILL and wider than the photo
    f = framing(mask)
    assert f.side == int(np.ceil(80 / FILL)) and f.left < 0
    img = np.arange(100 * 40, dtype=np.float32).reshape(100, 40)
    sq = crop(img, f, "edge")
    assert sq.shape == (f.side, f.side)
    assert sq[50 - f.top, 0] == img[50, 0]  # left of the photo: its first column repeated
    assert crop(mask.astype(np.uint8), f, "constant")[:, 0].sum() == 0


def test_grayscale_and_16_bit_inputs_are_handled(tiny_networks, tmp_path):
    photo, mask, _ = _person(tmp_path, mode="L")
    Image.fromarray((np.asarray(Image.open(mask)).astype(np.uint16) * 257)).save(tmp_path / "mask16.png")
    nets = load_networks("cpu", tiny_networks)
    record = infer(photo, tmp_path / "mask16.png", tmp_path / "b", size=64, networks=nets)
    assert any("grayscale" in n for n in record["notes"]) and any("16-bit" in n for n in record["notes"])
    assert load_scene(tmp_path / "b").mask.sum() > 0


def test_bad_inputs_name_the_file_and_the_problem(tiny_networks, tmp_path):
    photo, mask, inside = _person(tmp_path)
    nets = load_networks("cpu", tiny_networks)
    Image.fromarray(np.zeros((96, 64), np.uint8)).save(tmp_path / "empty.png")
    Image.fromarray(np.zeros((50, 64), np.uint8)).save(tmp_path / "small.png")
    tiny = np.zeros((96, 64), np.uint8)
    tiny[40:50, 30:33] = 255
    Image.fromarray(tiny).save(tmp_path / "tiny.png")
    (tmp_path / "broken.png").write_bytes(b"not a png")
    for p, m, message in ((photo, tmp_path / "empty.png", "no person in the mask"),
                          (photo, tmp_path / "small.png", "a mask must match its photo"),
                          (photo, tmp_path / "tiny.png", "pixels tall"),
                          (tmp_path / "broken.png", mask, "cannot read the photo"),
                          (tmp_path / "missing.jpg", mask, "photo not found")):
        with pytest.raises(InputError, match=message) as info:
            infer(p, m, tmp_path / "out", size=64, networks=nets)
        assert info.value.path is not None
    with pytest.raises(InputError, match="--size"):
        infer(photo, mask, tmp_path / "out", size=10_000, networks=nets)


def test_full_mask_is_relit_with_a_note(tiny_networks, tmp_path):
    photo, _, _ = _person(tmp_path)
    Image.fromarray(np.full((96, 64), 255, np.uint8)).save(tmp_path / "full.png")
    record = infer(photo, tmp_path / "full.png", tmp_path / "b", size=64, networks=load_networks("cpu", tiny_networks))
    assert any("whole photo" in n for n in record["notes"])
    scene = load_scene(tmp_path / "b")
    assert np.all(np.isfinite(scene.albedo)) and np.all(np.isfinite(scene.depth))


def test_bundle_is_inferred_once_and_then_cached(tiny_networks, tmp_path, monkeypatch):
    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache" / "lights"))
    photo, mask, _ = _person(tmp_path)
    first, cached = cached_bundle(photo, mask, size=64, networks_dir=tiny_networks)
    assert not cached and (first / "scene.json").is_file()
    again, cached = cached_bundle(photo, mask, size=64, networks_dir=tiny_networks)
    assert cached and again == first
    other, cached = cached_bundle(photo, mask, size=96, networks_dir=tiny_networks)
    assert not cached and other != first


def test_a_huge_photo_is_framed_and_downscaled(tiny_networks, tmp_path):
    h, w = 6000, 4000
    photo = np.zeros((h, w, 3), np.uint8)
    photo[..., 1] = 90
    mask = np.zeros((h, w), np.uint8)
    mask[1000:5200, 1700:2300] = 255
    photo[mask > 0] = (200, 150, 120)
    Image.fromarray(photo).save(tmp_path / "huge.jpg", quality=80)
    Image.fromarray(mask).save(tmp_path / "huge.png")
    record = infer(tmp_path / "huge.jpg", tmp_path / "huge.png", tmp_path / "b", size=128,
                   networks=load_networks("cpu", tiny_networks))
    assert record["photo_size"] == [w, h] and record["framing"]["side"] == int(np.ceil(4200 / FILL))
    assert load_scene(tmp_path / "b").mask.sum() > 0
