"""Every mode a shader branches on, named once.

Each family lists its modes' names in order; a mode's code is its position. GLSL receives every
code as a generated ``#define`` (``TONEMAP_ACES``, ``BACKGROUND_ENVIRONMENT``, ``PASS_HARD``, ...:
:func:`glsl_mode_defines`, prepended to every shader with :mod:`viewer.constants`), Python sets a
uniform with :func:`code`, and shaders compare names, never numbers (``tests/test_programs.py``
fails on a mode compared with a bare integer), as three.js generates its tone-map functions from
its enum. Adding a mode is adding its name here and its branch in the shader.
"""

from __future__ import annotations

MODES = {
    "TONEMAP": ("neutral", "aces", "reinhard", "clamp"),  # the display's tone curve (shaders/tonemap.glsl)
    "BACKGROUND": ("color", "photo", "environment", "transparent"),  # behind the person
    "VISIBILITY": ("soft", "hard", "none", "refined"),  # the shadows the composite uses
    "INSPECT": ("albedo", "normal", "depth", "specular", "roughness", "shadow"),  # an inspection view
    "PASS": ("off", "hard", "soft", "unshadowed"),  # what a light's pass computes
    "OUTPUT": ("display", "person_hdr", "composited_hdr", "background_display", "background_hdr"),  # what the frame composite writes
}


def code(family: str, name: str) -> int:
    """The code of mode ``name`` of ``family`` (a ValueError names the choices)."""
    names = MODES[family]
    if name not in names:
        raise ValueError(f"{family.lower()} mode must be one of {', '.join(names)}, got {name!r}")
    return names.index(name)


def glsl_mode_defines() -> list[str]:
    """``#define FAMILY_NAME code`` for every mode."""
    return [f"#define {family}_{name.upper()} {k}" for family, names in MODES.items() for k, name in enumerate(names)]
