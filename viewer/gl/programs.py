"""GLSL programs assembled from the files in shaders/ with ``#include "file.glsl"`` lines."""

from __future__ import annotations

import re
from pathlib import Path

import moderngl

from viewer.constants import glsl_defines
from viewer.resources import shader_dir
from viewer.shader_modes import glsl_mode_defines

GLSL_VERSION = "#version 410 core"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.M)


def shader_source(name: str, defines: dict | None = None, directory: Path | None = None,
                  files: list[str] | None = None, sources: dict | None = None) -> str:
    """The text of ``shaders/name`` with includes expanded (each file once), the shared constants
    (:mod:`viewer.constants`), the modes' names (:mod:`viewer.shader_modes`) and ``defines`` prepended.
    Each file's text starts with ``#line 1 k`` and the text after an include with the line it came
    from, so the GLSL compiler reports (source string k, line) of the ``.glsl`` file itself;
    ``files``, when given, receives the file names by k (:func:`explain_errors`); ``sources``: files given
    as text, by name, before the folder's (the soft-shadow method's ``soft_method.glsl``, :mod:`viewer.gl.soft`)."""
    directory = directory or shader_dir()
    seen: set[str] = set()
    files = files if files is not None else []

    def expand(fname: str) -> str:
        if fname in seen:
            return ""
        seen.add(fname)
        path = directory / fname
        if fname not in (sources or {}) and not path.is_file():
            raise FileNotFoundError(f"shader file not found: {path}")
        index = len(files)
        files.append(fname)
        out, last = [f"#line 1 {index}"], 0
        text = sources[fname] if fname in (sources or {}) else path.read_text()
        text = text if text.endswith("\n") else text + "\n"  # what follows an include starts on a line of its own
        for m in _INCLUDE.finditer(text):
            out.append(text[last:m.start()])
            out.append(expand(m.group(1)))
            line = text.count("\n", 0, m.end()) + 2  # the line after the include
            out.append(f"#line {line} {index}\n")
            last = m.end() + 1
        out.append(text[last:])
        return out[0] + "\n" + "".join(out[1:])

    lines = [GLSL_VERSION, *glsl_defines(), *glsl_mode_defines()]
    for key, value in (defines or {}).items():
        lines.append(f"#define {key} {value}" if value is not None else f"#define {key}")
    return "\n".join(lines) + "\n" + expand(name)


# Mesa: "0:12(5): error: ..."; NVIDIA: "0(12) : error ..."; the first number is the source string.
# Both become "file.glsl:12: error ...".
_ERROR_PLACE = re.compile(r"^(\d+)(?::(\d+)\(\d+\)|\((\d+)\) ?)", re.M)


def explain_errors(log: str, files: list[str], directory: Path) -> str:
    """A compiler log with each (source string, line) replaced by the ``.glsl`` file and line."""

    def place(m):
        k, line = int(m.group(1)), m.group(2) or m.group(3)
        return f"{directory / files[k]}:{line}" if k < len(files) else m.group(0)

    return _ERROR_PLACE.sub(place, log)


class ProgramCache:
    """Compiles each (vertex, fragment, defines) program once per context."""

    def __init__(self, ctx: moderngl.Context, directory: Path | None = None):
        self.ctx = ctx
        self.directory = directory or shader_dir()
        self._programs: dict = {}

    def get(self, vertex: str, fragment: str, sources: dict | None = None, **defines) -> moderngl.Program:
        """The program of these files and ``defines``; ``sources``: files given as text (:func:`shader_source`)."""
        key = (vertex, fragment, tuple(sorted(defines.items())), tuple(sorted((sources or {}).items())))
        prog = self._programs.get(key)
        if prog is None:
            texts = {}
            for stage, name in (("vertex_shader", vertex), ("fragment_shader", fragment)):
                files: list[str] = []
                texts[stage] = (shader_source(name, defines, self.directory, files, sources), files)
            try:
                prog = self.ctx.program(**{stage: text for stage, (text, _) in texts.items()})
            except moderngl.Error as exc:
                # moderngl names the stage that failed; its log's places are that stage's files
                failed = "fragment_shader" if "fragment_shader" in str(exc) else "vertex_shader"
                raise RuntimeError(f"compiling {vertex} + {fragment}: "
                                   f"{explain_errors(str(exc), texts[failed][1], self.directory)}") from None
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
    the context, whose owner releases them (the viewer's window)."""
    if ctx.extra is None:
        ctx.extra = {}
    if "programs" not in ctx.extra:
        ctx.extra["programs"] = ProgramCache(ctx)
    return ctx.extra["programs"]
