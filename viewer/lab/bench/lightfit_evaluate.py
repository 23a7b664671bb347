"""The shading error of a light set against a map's reference, on the fitting views and a held-out one.

Errors are relative L1 of linear shading, ``sum |model - reference| / sum reference`` over all pixels
and the seven rotations of the map:

- ``sphere``: diffuse + specular of the sphere view (no shadows);
- ``plane``: shadowed diffuse of the sphere-on-a-plane view (the fitting scene of Step 3);
- ``heldout``: shadowed diffuse of the box-on-a-plane view, which no method fits to.

Shadows of the lights are the twin's convolutional shadow maps with each light's own sigma, i.e.
what the GL engine draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from viewer.lighting.lightfit.problem import Problem, shadowed_views
from viewer.lighting.lightfit.reference import plane_reference
from viewer.lighting.lightfit.views import PlaneView, plane_view
from viewer.scene.area_lights import AreaLights


@dataclass(frozen=True)
class HeldOut:
    view: PlaneView
    reference: torch.Tensor  # (K, P, 3), normalized like the problem's references


def held_out(problem: Problem) -> HeldOut:
    view = plane_view("box", problem.settings.plane_resolution)
    ref = plane_reference(problem.samples, view, problem.rotations)
    return HeldOut(view, ref / problem.scale)


def relative_l1(model: torch.Tensor, reference: torch.Tensor) -> float:
    return float((model - reference).abs().sum() / reference.abs().sum().clamp(min=1e-30))


def shading_errors(problem: Problem, lights: AreaLights, heldout: HeldOut | None = None) -> dict:
    """{'sphere', 'plane'[, 'heldout']} relative L1 errors of ``lights`` (see the module docstring)."""
    s = problem.settings
    direction = torch.as_tensor(lights.direction, dtype=torch.float32)
    intensity = torch.as_tensor(lights.intensity, dtype=torch.float32) / problem.scale
    sigma = torch.as_tensor(lights.sigma, dtype=torch.float32)
    with torch.no_grad():
        diff, spec = problem.sphere_shading(direction, intensity)
        errors = {"sphere": relative_l1(torch.cat([diff, spec]), torch.cat([problem.sphere_diffuse, problem.sphere_specular]))}
        targets = [("plane", problem.plane, problem.plane_shadowed)]
        if heldout is not None:
            targets.append(("heldout", heldout.view, heldout.reference))
        for name, view, ref in targets:
            views = shadowed_views(view, lights.direction, problem.rotations, s.shadow_resolution, s.terms)
            errors[name] = relative_l1(views.shading(views.soft_visibility(sigma), intensity), ref)
    return errors
