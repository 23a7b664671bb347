"""``relight bench photos --set`` (viewer/lab/bench/photo_set.py, face_metrics.py): each figure
responds to what it measures, and the command runs the whole photo path on a real photo (the
bundled one) with the shared maps, writing its JSON and contact sheet."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
from conftest import SHARED_DATA

from viewer.lab.bench import face_metrics as fm
from viewer.lab.bench.photo_set import halves, terminator, white_shift

ROOT = Path(__file__).resolve().parents[1]


def _textured(h=96, w=96, seed=0):
    rng = np.random.default_rng(seed)
    base = np.full((h, w, 3), 0.4, np.float32) * (1.0 + 0.05 * rng.standard_normal((h, w, 1)).astype(np.float32))
    return np.clip(base, 0.01, None)


def test_holes_count_the_dark_share_of_the_skin():
    photo = _textured()
    skin = np.zeros(photo.shape[:2], bool)
    skin[16:80, 16:80] = True
    assert fm.holes(photo * 2.0, photo, skin) == 0.0  # relit brighter everywhere: no hole
    relit = photo.copy()
    relit[16:32, 16:80] *= 0.05  # a black block over a quarter of the skin
    assert abs(fm.holes(relit, photo, skin) - 0.25) < 0.03
    assert fm.holes(relit, photo, np.zeros_like(skin)) is None


def test_speckle_is_one_for_the_photos_detail_and_more_for_added_noise():
    photo = _textured()
    region = np.ones(photo.shape[:2], bool)
    assert abs(fm.speckle(photo * 3.0, photo, region) - 1.0) < 1e-3  # the same detail, lit brighter
    noisy = photo * (1.0 + 0.2 * np.random.default_rng(1).standard_normal(photo.shape[:2])[..., None]).astype(np.float32)
    assert fm.speckle(np.clip(noisy, 0.001, None), photo, region) > 1.5


def test_white_shift_is_zero_for_white_kept_white_and_grows_with_a_tint():
    h = w = 64
    photo = np.full((h, w, 3), 235, np.uint8)
    alpha = np.ones((h, w), np.float32)
    assert white_shift(photo, photo, alpha) == 0.0
    tinted = photo.copy()
    tinted[..., 2] = 200  # a yellow cast
    assert white_shift(tinted, photo, alpha) > 10.0
    assert white_shift(photo, photo, np.zeros((h, w), np.float32)) is None


def test_terminator_says_softer_and_warmer():
    h = w = 64
    x = np.linspace(-1, 1, w, dtype=np.float32)
    off = np.repeat(np.clip(x * 20, 0.02, 1.0)[None, :, None], h, 0).repeat(3, axis=2)  # a hard edge, grey
    soft = np.clip(x * 5, 0.02, 1.0)
    on = np.stack([np.repeat(np.clip(x * 5 + 0.05, 0.02, 1.0)[None], h, 0)] + [np.repeat(soft[None], h, 0)] * 2, -1)
    figures = terminator(on, off, np.ones((h, w), bool))
    assert figures["sharpness"] < 0.7 and figures["warmth"] > 1.0


def test_the_halves_are_balanced_and_stable():
    names = [Path(f"photo_{i}.jpg") for i in range(11)]
    parts = halves(names)
    assert abs(sum(v == "tune" for v in parts.values()) - 5.5) <= 0.5
    assert parts == halves(list(reversed(names)))


def test_the_bench_runs_the_photo_path_on_a_real_photo(tmp_path):
    photos = tmp_path / "set"
    photos.mkdir()
    shutil.copy(ROOT / "assets" / "photos" / "underpass.jpg", photos / "underpass.jpg")
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "viewer.cli.main", "bench", "photos", "--set", str(photos), "--maps",
                          str(SHARED_DATA / "hdri"), "-o", str(out)], capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    result = json.loads((out / "photo_set.json").read_text())
    (row,) = result["photos"]
    assert row["face"] is not None and row["face"]["skin_pixels"] > 200
    for lighting in ("studio", "park", "front+fill"):
        assert 0.0 <= row["lightings"][lighting]["holes"] <= 0.01  # no black wedge on the bundled photo's face
        assert 0.5 < row["lightings"][lighting]["speckle_face"] < 1.3
    assert 0.8 <= row["lightings"]["studio"]["detail_kept"] <= 1.2 and row["light_moved"] >= 0.2
    assert 0.95 <= row["terminator"]["sharpness"] <= 1.0 and row["terminator"]["warmth"] >= 1.0
    assert (out / row["contact_sheet"]).is_file() and "| underpass.jpg |" in run.stdout
