"""A non-editable install (`pip install .`) carries the shaders and the bundled assets."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_wheel_install_finds_shaders_and_assets(tmp_path):
    src = tmp_path / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".venv", ".git", "out", "build", "*.egg-info", "__pycache__", ".pytest_cache"))
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--target", str(target), str(src)],
                   check=True, capture_output=True)
    code = (
        "import viewer.resources as r, viewer.gl.programs as p;"
        "print(r.shader_dir()); print(r.sample_scene_dir());"
        "assert (r.sample_scene_dir() / 'scene.json').is_file();"
        "assert (r.asset_dir() / 'envmaps' / 'immenstadter_horn_256.lights.json').is_file();"
        "assert 'disney_specular_shading' in p.shader_source('light_pass.frag.glsl')"
    )
    env = {**os.environ, "PYTHONPATH": str(target)}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    shader_dir, scene_dir = out.stdout.split()
    assert shader_dir.startswith(str(target)) and scene_dir.startswith(str(target))


LAB = ("viewer.lab",)  # datasets, ground truth, training, benchmarks
_WITHOUT_LAB = f"""
import importlib.abc, sys
class NoLab(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if any(name == lab or name.startswith(lab + ".") for lab in {LAB!r}):
            raise ImportError("the product imported the lab module " + name)
sys.meta_path.insert(0, NoLab())
from viewer.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def test_the_product_runs_without_the_lab(tmp_path):
    """infer (automatic mask), render with refined shadows, fit-lights, plate-light and render onto a plate, with every lab module
    unimportable: the product never imports datasets, ground truth, training or benchmarks."""
    photo = ROOT / "assets" / "photos" / "underpass.jpg"
    env_map = ROOT / "assets" / "envmaps" / "venice_sunset_256.hdr"
    for args in (["infer", str(photo), "-o", str(tmp_path / "b"), "--max-size", "320", "--size", "128"],
                 ["render", str(tmp_path / "b"), "--env", str(env_map), "--visibility", "refined", "-o", str(tmp_path / "x.png")],
                 ["fit-lights", str(env_map), "-n", "4", "--method", "median-cut", "-o", str(tmp_path / "l.json")],
                 ["plate-light", str(photo), "-o", str(tmp_path / "plate.exr")],
                 ["render", str(tmp_path / "b"), "--plate", str(photo), "-n", "4", "-o", str(tmp_path / "on_plate.png")]):
        res = subprocess.run([sys.executable, "-c", _WITHOUT_LAB, *args], capture_output=True, text=True,
                             env={**os.environ, "RELIGHT_CACHE": str(tmp_path / "cache")})
        assert res.returncode == 0, res.stderr[-2000:]
    assert (tmp_path / "x.png").is_file() and (tmp_path / "l.json").is_file() and (tmp_path / "on_plate.png").is_file()
