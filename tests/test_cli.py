"""The command line: the demo writes real files; bad input is one clear line, not a traceback."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from viewer.cli import main
from viewer.imageio import read_exr, read_png


def test_demo_writes_png_and_exr(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    png, exr = tmp_path / "demo.png", tmp_path / "demo.exr"
    assert str(png) in out and str(exr) in out
    img, hdr = read_png(png), read_exr(exr)
    assert img.shape == (512, 512, 3) and hdr.shape == (512, 512, 3)
    assert np.isfinite(hdr).all() and hdr.max() > 0.05  # lit, not a silent black image
    assert img.std() > 0.05
    assert (tmp_path / "demo_passes.png").is_file()


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "viewer.cli", *args], capture_output=True, text=True)


def test_bad_inputs_give_one_line_errors(tmp_path):
    bad_lights = tmp_path / "lights.json"
    bad_lights.write_text('{"format": "relight-lights", "lights": [{"direction": [0, 2, 0], "sigma": 1, "intensity": [1, 1, 1]}]}')
    from viewer.resources import sample_scene_dir

    for args, message in (
        (("render", str(tmp_path / "nope"), str(bad_lights)), "scene bundle directory not found"),
        (("render", str(sample_scene_dir()), str(bad_lights)), "not a unit vector"),
        (("render", str(sample_scene_dir()), str(tmp_path / "missing.json")), "light file not found"),
    ):
        res = run_cli(*args)
        assert res.returncode == 2, res.stderr
        assert "Traceback" not in res.stderr
        assert message in res.stderr and res.stderr.startswith("relight: error: ")


def test_viewing_precomputed_maps_never_imports_torch(tmp_path):
    code = ("import sys; from viewer.cli import main; main(['demo', '-o', sys.argv[1]]);"
            "assert 'torch' not in sys.modules, 'torch was imported'")
    res = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
