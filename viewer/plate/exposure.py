"""The exposure of a person lit by the user's own light on a plate (``--env MAP`` or ``--lights FILE``
with ``--plate``): the stops that give them, over their normals, the diffuse light the plate's own
light gives them there, so that they sit in the plate as bright as the plate's light would make them
while keeping the map's direction and colour (the compositor's workflow: their map lights the
person, the plate sets the level). Without it they kept their own photo's brightness, which on a dim
overcast street was far too bright.

Both lights are compared as irradiance: a map by its order-2 spherical harmonics
(:mod:`viewer.lighting.sh`, exact for diffuse light), a light file by its lights as points (their
sizes do not change a diffuse surface's light much); the mean luminance of that irradiance over the
person's normals (camera space) under each, the user's turned by the look's yaw and tilt as the
engine turns it.
"""

from __future__ import annotations

import numpy as np

from viewer.lighting.envmap import LUMINANCE, EnvMap
from viewer.scene.area_lights import AreaLights, rotation_matrix
from viewer.scene.look import EXPOSURE_LIMIT

NORMALS = 20000  # of the person's normals taken (evenly) for the mean
MAP_WIDTH = 256  # a map is shrunk to this width before its harmonics (the diffuse light does not need more)


def mean_irradiance(light: EnvMap | AreaLights, normals: np.ndarray, yaw: float = 0.0, tilt: float = 0.0) -> float:
    """The mean luminance of the irradiance ``light`` (turned by ``yaw`` and ``tilt`` as the look turns a
    map) gives surfaces of ``normals`` (N, 3)."""
    from viewer.lighting import sh

    turn = rotation_matrix(yaw, tilt)
    n = np.asarray(normals, np.float64) @ turn  # each normal turned back: the map's light at R^T n
    if isinstance(light, AreaLights):
        cos = np.clip(n @ np.asarray(light.direction, np.float64).T, 0.0, None)
        e = cos @ np.asarray(light.intensity, np.float64)
    else:
        small = light.downsampled(MAP_WIDTH) if light.width > MAP_WIDTH else light
        e = sh.irradiance(sh.project(small), n.astype(np.float32))
    return float(np.clip(e @ LUMINANCE, 0.0, None).mean())


def person_exposure(plate_light: EnvMap, light: EnvMap | AreaLights, scene, look) -> float:
    """:func:`matched_exposure` for ``scene``'s person (its normals inside its mask) under ``look``'s turn."""
    return matched_exposure(plate_light, light, scene.normal[scene.mask], look.yaw, look.tilt)


def matched_exposure(plate_light: EnvMap, light: EnvMap | AreaLights, normals: np.ndarray, yaw: float = 0.0,
                     tilt: float = 0.0) -> float:
    """Stops for a person of ``normals`` lit by ``light`` (turned by ``yaw``, ``tilt``) to get the
    diffuse light ``plate_light`` gives them; 0 where either gives none."""
    normals = np.asarray(normals, np.float32).reshape(-1, 3)
    normals = normals[:: max(len(normals) // NORMALS, 1)]
    if not len(normals):
        return 0.0
    plate = mean_irradiance(plate_light, normals)
    own = mean_irradiance(light, normals, yaw, tilt)
    if not (plate > 0.0 and own > 0.0 and np.isfinite(plate) and np.isfinite(own)):
        return 0.0
    return float(np.clip(np.log2(plate / own), -EXPOSURE_LIMIT, EXPOSURE_LIMIT))
