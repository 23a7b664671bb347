"""Environment map -> N area lights: reference shading, the fitters, their cache and pictures.

Modules: :mod:`.samples` (the map as directional samples), :mod:`.sphere_lobes` (the sphere view
and its shading in numpy, with slopes), :mod:`.sphere_fit` (the default fits' Step 2 in numpy),
:mod:`.views` (plane views with analytic visibility), :mod:`.reference` (their reference shading),
:mod:`.problem` (one map's fitting problem and the lights' differentiable shading in torch),
:mod:`.paper` (the paper's method), :mod:`.fit` (the methods, named in :mod:`.methods`),
:mod:`.settings`, :mod:`.adam`, :mod:`.cache` (content-addressed cache), :mod:`.plot` (lights on the map).
Importing this package does not import torch, and neither do the default fits (``instant``,
``fast``): only the paper's method and the benchmark's errors do.
"""

from viewer.lighting.lightfit.cache import cache_dir, cache_path, lights_for_map, map_hash
from viewer.lighting.lightfit.methods import DEFAULT_METHOD, METHODS

__all__ = ["DEFAULT_METHOD", "METHODS", "cache_dir", "cache_path", "lights_for_map", "map_hash"]
