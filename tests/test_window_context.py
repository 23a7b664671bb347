"""The same engine renders in a GLFW window's context (here GLFW's null platform over EGL, so no X
server is needed) and gives the same pixels as the headless EGL context."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

SCRIPT = r"""
import sys, numpy as np
sys.path.insert(0, sys.argv[1])
import imgui_bundle  # sets PYGLFW_LIBRARY to its own libglfw, which has the null platform
import glfw, moderngl
from viewer.lab.scenes import plane_and_box
from viewer.gl import Engine, EngineOptions
from viewer.scene.area_lights import AreaLights
glfw.init_hint(glfw.PLATFORM, glfw.PLATFORM_NULL)
assert glfw.init(), "glfw init failed"
glfw.window_hint(glfw.CONTEXT_CREATION_API, glfw.EGL_CONTEXT_API)
glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 4)
glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 1)
glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
glfw.window_hint(glfw.VISIBLE, False)
win = glfw.create_window(64, 64, "relight", None, None)
assert win, "no window"
glfw.make_context_current(win)
ctx = moderngl.create_context(require=410)
eng = Engine(ctx, plane_and_box(48), EngineOptions(shadow_resolution=128, shadow_step=1))
d = np.array([[0.3, 0.4, 1.0]], np.float32); d /= np.linalg.norm(d)
eng.set_lights(AreaLights(d, [4.0], [[1, 1, 1]]))
eng.render()
np.save(sys.argv[2], eng.output.read_hdr())
glfw.terminate()
"""


def test_engine_in_glfw_context_matches_headless(ctx, tmp_path):
    from viewer.gl import Engine, EngineOptions
    from viewer.lab.scenes import plane_and_box
    from viewer.scene.area_lights import AreaLights

    out = tmp_path / "window.npy"
    res = subprocess.run([sys.executable, "-c", SCRIPT, str(Path(__file__).parent), str(out)], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    eng = Engine(ctx, plane_and_box(48), EngineOptions(shadow_resolution=128, shadow_step=1))
    d = np.array([[0.3, 0.4, 1.0]], np.float32)
    d /= np.linalg.norm(d)
    eng.set_lights(AreaLights(d, [4.0], [[1, 1, 1]]))
    eng.render()
    np.testing.assert_allclose(np.load(out), eng.output.read_hdr(), atol=1e-6)
    eng.release()
