"""OpenGL contexts: headless EGL (software Mesa here, a GPU elsewhere) or a window's context.

The engine takes any moderngl context, so the same engine draws into a GLFW window later.
"""

from __future__ import annotations

import moderngl

REQUIRED_VERSION = 410
MIN_ADDRESS_SPACE_MB = 1536  # llvmpipe's threads and JIT: a render crashed (SIGSEGV) under ulimit -v 1143 MB, ran at 1200


def check_address_space() -> None:
    """One line, before any native GL code runs, when the process's address space is limited (``ulimit
    -v``) below what Mesa needs: there it crashes in native code, where no message can be given."""
    import resource

    from viewer.errors import InputError

    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY and soft < MIN_ADDRESS_SPACE_MB << 20:
        raise InputError(None, f"the process's address space is limited to {soft >> 20} MB (ulimit -v): OpenGL on Mesa needs "
                               f"at least {MIN_ADDRESS_SPACE_MB} MB; raise the limit (ulimit -v unlimited)")


def create_headless_context() -> moderngl.Context:
    """A standalone EGL context (OpenGL >= 4.1 core); one line naming the likely causes when there
    is none (the user's input is not one of them: an ``InputError`` without a file)."""
    import os

    from viewer.errors import InputError

    check_address_space()
    try:
        return moderngl.create_standalone_context(backend="egl", require=REQUIRED_VERSION)
    except Exception as exc:
        said = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        override = os.environ.get("MESA_GL_VERSION_OVERRIDE")
        why = (f"MESA_GL_VERSION_OVERRIDE={override} asks Mesa for less than the OpenGL "
               f"{REQUIRED_VERSION // 100}.{REQUIRED_VERSION % 100 // 10} this program needs: unset it" if override else
               "is Mesa's EGL installed (Debian: apt-get install libegl1 libgl1)? is the process's memory limited "
               "(ulimit -v)?")
        raise InputError(None, f"cannot create a headless OpenGL context through EGL ({said}); {why}") from None


def make_current(ctx: moderngl.Context):
    """Make ``ctx`` the thread's current GL context. Creating another context (the training
    loader's, a dataset renderer's) makes that one current, and GL object names belong to one
    context, so every engine entry point calls this. moderngl has no call for it: entering the
    context does it, and leaving it (``with ctx:``) would make *no* context current (glcontext
    releases rather than restores), so it is entered and never left."""
    ctx.__enter__()


def describe(ctx: moderngl.Context) -> str:
    info = ctx.info
    return f"{info.get('GL_RENDERER', '?')} (OpenGL {ctx.version_code})"
