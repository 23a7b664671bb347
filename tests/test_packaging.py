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
