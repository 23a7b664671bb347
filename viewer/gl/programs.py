"""GLSL programs assembled from the files in shaders/ with ``#include "file.glsl"`` lines."""

from __future__ import annotations

import re
from pathlib import Path

import moderngl

from ..resources import shader_dir

GLSL_VERSION = "#version 410 core"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.M)


def shader_source(name: str, defines: dict | None = None, directory: Path | None = None) -> str:
    """The text of ``shaders/name`` with includes expanded (each file once) and defines prepended."""
    directory = directory or shader_dir()
    seen: set[str] = set()

    def expand(fname: str) -> str:
        if fname in seen:
            return ""
        seen.add(fname)
        path = directory / fname
        if not path.is_file():
            raise FileNotFoundError(f"shader file not found: {path}")
        text = path.read_text()
        return _INCLUDE.sub(lambda m: expand(m.group(1)), text)

    lines = [GLSL_VERSION]
    for key, value in (defines or {}).items():
        lines.append(f"#define {key} {value}" if value is not None else f"#define {key}")
    lines.append("#line 1")
    return "\n".join(lines) + "\n" + expand(name)


class ProgramCache:
    """Compiles each (vertex, fragment, defines) program once per context."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self._programs: dict = {}

    def get(self, vertex: str, fragment: str, **defines) -> moderngl.Program:
        key = (vertex, fragment, tuple(sorted(defines.items())))
        prog = self._programs.get(key)
        if prog is None:
            try:
                prog = self.ctx.program(
                    vertex_shader=shader_source(vertex, defines), fragment_shader=shader_source(fragment, defines)
                )
            except moderngl.Error as exc:
                raise RuntimeError(f"compiling {vertex} + {fragment}: {exc}") from None
            self._programs[key] = prog
        return prog

    def release(self):
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()


def shared_programs(ctx: moderngl.Context) -> ProgramCache:
    """The context's one program cache, kept in ``ctx.extra``: every engine made on a context
    (the inference's, the viewer's final and preview engines, a preset's new one) compiles each
    program once (about a second of llvmpipe's time each otherwise); the programs live as long as
    the context."""
    if ctx.extra is None:
        ctx.extra = {}
    if not isinstance(ctx.extra, dict):
        return ProgramCache(ctx)
    return ctx.extra.setdefault("programs", ProgramCache(ctx))
