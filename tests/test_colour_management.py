"""Colours as the photo meant them (issue 43): a photo in Adobe RGB or Display P3, its profile
embedded, is read in sRGB by LittleCMS (Pillow's ImageCms) and relit as the same photo converted to
sRGB first; a mask's values are never converted."""

from __future__ import annotations

import io
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest
from conftest import SHARED_DATA
from PIL import Image, ImageCms

from viewer.lab.icc_profiles import ADOBE_RGB, DISPLAY_P3, matrix_trc_profile
from viewer.photo.frames import read_mask, read_photo
from viewer.resources import asset_dir

PHOTO = asset_dir() / "photos" / "underpass.jpg"
SRGB = ImageCms.createProfile("sRGB")


def _in_space(space, tmp_path):
    """The bundled photo in ``space`` with its profile embedded, and the same converted back to sRGB."""
    icc = matrix_trc_profile(space)
    profile = ImageCms.ImageCmsProfile(io.BytesIO(icc))
    with Image.open(PHOTO) as im:
        im = im.convert("RGB")
        im.thumbnail((400, 600))
    wide = ImageCms.profileToProfile(im, SRGB, profile, outputMode="RGB")
    tagged = tmp_path / f"wide_{space[0][:5]}.png"
    wide.save(tagged, icc_profile=icc)
    converted = tmp_path / f"srgb_{space[0][:5]}.png"
    ImageCms.profileToProfile(wide, profile, SRGB, outputMode="RGB").save(converted)
    untagged = tmp_path / f"untagged_{space[0][:5]}.png"
    wide.info.pop("icc_profile", None)
    wide.save(untagged)  # what a reader that ignores profiles sees
    return tagged, converted, untagged


def _relit(photo, out, tmp_path):
    env = SHARED_DATA / "hdri" / "potsdamer_platz_1k.hdr"
    bundle = out.with_suffix("")
    environ = {**os.environ, "RELIGHT_CACHE": str(tmp_path / "cache" / "lights")}
    for args in (["infer", str(photo), "--max-size", "600", "-o", str(bundle)],
                 ["render", str(bundle), "--env", str(env), "--exposure", "0", "--background", "transparent", "-o", str(out)]):
        res = subprocess.run([sys.executable, "-m", "viewer.cli.main", *args], capture_output=True, text=True, env=environ,
                             timeout=600)
        assert res.returncode == 0, res.stderr
    with Image.open(out) as im:
        return np.asarray(im.convert("RGBA"))


def _delta_e(a, b) -> float:
    """CIE76 in OpenCV's 8-bit Lab, mean over the pixels of alpha > 200 in both (the issue's measure)."""
    both = (a[..., 3] > 200) & (b[..., 3] > 200)
    la = cv2.cvtColor(np.ascontiguousarray(a[..., :3]), cv2.COLOR_RGB2LAB).astype(np.float64)
    lb = cv2.cvtColor(np.ascontiguousarray(b[..., :3]), cv2.COLOR_RGB2LAB).astype(np.float64)
    return float(np.linalg.norm(la - lb, axis=-1)[both].mean())


def test_a_photo_in_a_wide_gamut_profile_is_read_in_srgb(tmp_path):
    for space in (ADOBE_RGB, DISPLAY_P3):
        tagged, converted, untagged = _in_space(space, tmp_path)
        notes: list = []
        ours = read_photo(tagged, notes).astype(np.float64)
        assert any("converted from its embedded profile" in n for n in notes)
        reference = read_photo(converted, []).astype(np.float64)
        ignored = np.abs(read_photo(untagged, []).astype(np.float64) - reference).mean()
        assert np.abs(ours - reference).mean() < 0.25 * ignored  # the same conversion (LittleCMS), to rounding
        assert ignored > 1.5  # and it matters (a grey underpass: 2.1 levels on average)


def test_a_masks_values_are_never_converted(tmp_path):
    mask = np.zeros((64, 48), np.uint8)
    mask[10:50, 10:40] = 255
    mask[10:50, 39] = 128  # a soft edge
    path = tmp_path / "m.png"
    Image.fromarray(mask).convert("RGB").save(path, icc_profile=matrix_trc_profile(ADOBE_RGB))
    read = read_mask(path, (64, 48), [])
    assert np.allclose(read, mask / 255, atol=1e-3)  # an Adobe RGB conversion would have moved 128 to about 120


@pytest.mark.parametrize("space", [ADOBE_RGB, DISPLAY_P3], ids=["adobe-rgb", "display-p3"])
def test_relit_in_a_wide_gamut_profile_as_relit_converted_first(tmp_path, space):
    """The issue's target: relit under potsdamer_platz (--exposure 0, transparent), within Delta E 3
    of the photo converted to sRGB first."""
    tagged, converted, untagged = _in_space(space, tmp_path)
    reference = _relit(converted, tmp_path / "reference.png", tmp_path)
    assert _delta_e(_relit(tagged, tmp_path / "tagged.png", tmp_path), reference) <= 3.0
