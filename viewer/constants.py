"""Constants the GLSL shaders and the Python code share, in one place.

Every entry of :data:`GLSL_CONSTANTS` reaches every shader as a generated ``#define``
(:func:`viewer.gl.programs.shader_source`), and the torch twin and the numpy code import the same
names, so the two sides cannot drift apart. (Values that vary per draw, such as the CSM offset and
clamp of ``viewer.scene.shadow_space.csm_constants``, are uniforms set from Python instead.)
"""

from __future__ import annotations

import math

PI = math.pi
MIN_ALPHA = 1e-3  # GGX alpha = max(roughness^2, MIN_ALPHA): roughness 0 stays finite
SPECULAR_SCALE = 0.08  # Disney: F0 = SPECULAR_SCALE * specular
FILLED_MIN_COVERAGE = 0.05  # filled_sample: mask coverage below which a coarser mip level is read
TONEMAP_INPUT_MAX = 1e6  # the ACES curve is 1 long before; beyond, x^2 would overflow float32
SHEEN_DETAIL_MIN, SHEEN_DETAIL_MAX = 0.25, 4.0  # bounds of the factor the albedo's fine detail gives the sheen (frame_composite)
TONEMAP_KNEE = 0.76  # the neutral tone curve is linear up to this (Khronos PBR Neutral's start of compression)
TONEMAP_DESATURATION = 0.15  # the neutral curve's move towards white per unit compressed away (Khronos PBR Neutral's)

GLSL_CONSTANTS = {"PI": PI, "MIN_ALPHA": MIN_ALPHA, "SPECULAR_SCALE": SPECULAR_SCALE,
                  "FILLED_MIN_COVERAGE": FILLED_MIN_COVERAGE, "TONEMAP_INPUT_MAX": TONEMAP_INPUT_MAX,
                  "TONEMAP_KNEE": TONEMAP_KNEE, "TONEMAP_DESATURATION": TONEMAP_DESATURATION,
                  "SHEEN_DETAIL_MIN": SHEEN_DETAIL_MIN, "SHEEN_DETAIL_MAX": SHEEN_DETAIL_MAX}


def glsl_defines() -> list[str]:
    """The ``#define`` lines of :data:`GLSL_CONSTANTS` (floats written as GLSL float literals)."""
    return [f"#define {name} {float(value)!r}" for name, value in GLSL_CONSTANTS.items()]
