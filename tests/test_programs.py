"""GLSL assembly: includes keep their file and line, so a compile error names the .glsl file and
the line that holds it."""

from __future__ import annotations

import re
import shutil

import pytest

from viewer.gl.programs import ProgramCache, explain_errors, shader_dir
from viewer.scene.look import TONEMAPS


def _broken_copy(tmp_path, fname: str, after_line: int):
    """The shader folder copied, with a line that is not GLSL inserted after ``after_line``."""
    for p in shader_dir().glob("*.glsl"):
        shutil.copy(p, tmp_path)
    lines = (tmp_path / fname).read_text().splitlines()
    lines.insert(after_line, "this is not glsl;")
    (tmp_path / fname).write_text("\n".join(lines) + "\n")
    return after_line + 1  # the broken line's number


@pytest.mark.parametrize("fname", ["csm.glsl", "light_pass.frag.glsl"])
def test_a_compile_error_names_the_file_and_line(ctx, tmp_path, fname):
    text = (shader_dir() / fname).read_text().splitlines()
    # in the main file: a line after its includes, so the numbering must resume after each include
    after = max(i for i, l in enumerate(text) if l.startswith("#include")) + 2 if fname.endswith(".frag.glsl") else 5
    line = _broken_copy(tmp_path, fname, after)
    with pytest.raises(RuntimeError) as info:
        ProgramCache(ctx, tmp_path).get("fullscreen.vert.glsl", "light_pass.frag.glsl", TERMS=4, SPECULAR=None)
    message = str(info.value)
    assert f"{tmp_path / fname}:{line}: error" in message, message
    assert not re.search(r"^\d+:\d+\(\d+\)", message, re.M)  # no raw (source string, line) left


@pytest.mark.parametrize("log", [
    '0:18(1): error: syntax error, unexpected NEW_IDENTIFIER',  # Mesa (llvmpipe)
    '0(18) : error C0000: syntax error, unexpected reserved word "this" at token "this"',  # NVIDIA 580 (an H200)
])
def test_each_compilers_log_names_the_file(tmp_path, log):
    """Mesa's and NVIDIA's logs place an error differently; both read as file:line: error."""
    message = explain_errors(log, ["light_pass.frag.glsl"], tmp_path)
    assert message.startswith(f"{tmp_path / 'light_pass.frag.glsl'}:18: error"), message
    assert explain_errors(log.replace("0", "3", 1), ["a.glsl"], tmp_path) == log.replace("0", "3", 1)  # unknown string kept


def test_the_shipped_shaders_compile(ctx):
    cache = ProgramCache(ctx)
    for frag in sorted(p.name for p in shader_dir().glob("*.frag.glsl")):
        vert = "shadow_map.vert.glsl" if frag.startswith("shadow_map") else "fullscreen.vert.glsl"
        cache.get(vert, frag, TERMS=4, MAX_LIGHTS=16, MAX_CONTACT_POINTS=64, SCATTER_TAPS=13)


def test_shared_constants_come_from_one_place():
    """viewer.constants reaches every shader as #defines; no shader restates a value, and the torch
    twin uses the same objects."""
    import viewer.twin.brdf as twin_brdf
    from viewer.constants import GLSL_CONSTANTS, MIN_ALPHA, SPECULAR_SCALE
    from viewer.gl.programs import shader_source

    for shader in ("light_pass.frag.glsl", "frame_composite.frag.glsl", "csm_basis.frag.glsl"):
        src = shader_source(shader)
        for name, value in GLSL_CONSTANTS.items():
            assert f"#define {name} {float(value)!r}\n" in src
    for path in shader_dir().glob("*.glsl"):
        text = path.read_text()
        for literal in ("3.14159", "0.08 *", "MIN_ALPHA =", "FILLED_MIN_COVERAGE ="):
            assert literal not in text, (path.name, literal)
    assert twin_brdf.MIN_ALPHA is MIN_ALPHA and twin_brdf.SPECULAR_SCALE is SPECULAR_SCALE


MODE = r"(?:op|\w*(?:mode|_op|view|channel)\w*)(?:\[[^\]]*\])?"  # a mode's uniform, parameter or array element
MODE_COMPARISON = re.compile(rf"\b{MODE}\s*[!=]=\s*\d+\b|\b\d+\s*[!=]=\s*{MODE}")


def test_shaders_compare_modes_by_name_not_by_number():
    """Modes are named once (viewer.shader_modes) and reach GLSL as #defines: a shader that compares
    a mode with a bare integer would drift from Python's numbering."""
    from viewer.shader_modes import MODES, glsl_mode_defines

    bare = [f"{p.name}: {m.group(0)}" for p in shader_dir().glob("*.glsl") for m in MODE_COMPARISON.finditer(p.read_text())]
    assert bare == []
    used = "".join(p.read_text() for p in shader_dir().glob("*.glsl"))
    defined = {line.split()[1] for line in glsl_mode_defines()}
    assert len(defined) == sum(len(v) for v in MODES.values())
    for family in MODES:  # every family is compared by name somewhere
        assert any(name in used for name in defined if name.startswith(family + "_")), family


def test_the_tone_curves_in_glsl_and_in_numpy_agree(ctx, tmp_path):
    """shaders/tonemap.glsl drawn over inputs from 0 to past its cap, grey and coloured, against
    viewer.output.render's numpy curves (the auto exposure and the white warning use them)."""
    import numpy as np

    from viewer.output.render import tonemap
    from viewer.shader_modes import code

    for p in shader_dir().glob("*.glsl"):
        shutil.copy(p, tmp_path)
    (tmp_path / "tonemap_probe.frag.glsl").write_text(
        '#include "tonemap.glsl"\nuniform sampler2D values;\nuniform int op;\nout vec4 color;\n'
        "void main() { color = vec4(tonemap(texelFetch(values, ivec2(gl_FragCoord.xy), 0).rgb, op), 1.0); }\n")
    x = np.concatenate([np.linspace(0, 4, 200), np.geomspace(4, 1e8, 56)]).astype(np.float32)
    grey = np.repeat(x[:, None], 3, axis=1)
    values = np.concatenate([grey, grey * np.float32([1.0, 0.45, 0.1]), grey * np.float32([0.2, 0.3, 1.0])]).astype(np.float32)
    tex = ctx.texture((len(values), 1), 3, values.tobytes(), dtype="f4")
    out = ctx.texture((len(values), 1), 4, dtype="f4")
    fbo = ctx.framebuffer([out])
    prog = ProgramCache(ctx, tmp_path).get("fullscreen.vert.glsl", "tonemap_probe.frag.glsl")
    vao = ctx.vertex_array(prog, [])
    for op in TONEMAPS:
        prog["values"], prog["op"] = 0, code("TONEMAP", op)
        fbo.use()
        tex.use(0)
        vao.render(vertices=3)
        got = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(-1, 4)[:, :3]
        assert np.abs(got - tonemap(values, op)).max() < 1e-5, op
    for r in (vao, fbo, out, tex):
        r.release()
