"""GLSL assembly: includes keep their file and line, so a compile error names the .glsl file and
the line that holds it."""

from __future__ import annotations

import re
import shutil

import pytest

from viewer.gl.programs import ProgramCache, shader_dir


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


def test_the_shipped_shaders_compile(ctx):
    cache = ProgramCache(ctx)
    for frag in sorted(p.name for p in shader_dir().glob("*.frag.glsl")):
        vert = "shadow_map.vert.glsl" if frag.startswith("shadow_map") else "fullscreen.vert.glsl"
        cache.get(vert, frag, TERMS=4, MAX_LIGHTS=16, MAX_CONTACT_POINTS=64)


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
