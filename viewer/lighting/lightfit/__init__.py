"""Environment map -> N area lights: reference shading, the fitters, their cache and pictures.

Modules: :mod:`.samples` (the map as directional samples), :mod:`.views` (fitting scenes with
analytic visibility), :mod:`.reference` (reference shading), :mod:`.problem` (one map's fitting
problem and the lights' differentiable shading), :mod:`.fit` (the methods, named in :mod:`.methods`),
:mod:`.cache` (content-addressed cache), :mod:`.plot` (lights on the map).
Importing this package does not import torch (only fitting does), so viewing cached lights
stays light.
"""

from viewer.lighting.lightfit.cache import cache_dir, cache_path, lights_for_map, map_hash
from viewer.lighting.lightfit.methods import DEFAULT_METHOD, METHODS

__all__ = ["DEFAULT_METHOD", "METHODS", "cache_dir", "cache_path", "lights_for_map", "map_hash"]
