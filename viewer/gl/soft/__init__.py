"""Soft shadows, a family: each method is one module of this folder that registers itself
(:func:`register_soft_method`), as Mitsuba 3's integrators do (``register_integrator``). Adding a
method is adding a file here (a :class:`SoftMethod` subclass, registered) with its GLSL; the engine,
the ground shadow, ``--soft``'s choices, :class:`viewer.gl.options.EngineOptions` and the torch twin
find it by name (:func:`soft_method`).

A method gives (the shipped ones: :mod:`viewer.gl.soft.contact_hardening`, :mod:`viewer.gl.soft.convolutional_shadow_map`):

- ``glsl()``: its GLSL, defining ``float soft_visibility(int j, sampler2D shadow_map, sampler2D
  filtered_basis, vec3 uvd, vec3 n, vec3 l, float bias)`` (light ``j``'s soft visibility at the
  receiver ``uvd`` of its shadow map, ``n`` its normal, ``l`` the light; the uniforms of
  ``shaders/light_visibility.glsl`` in scope), included where that file includes
  ``soft_method.glsl``;
- ``prefiltered``: whether it reads the CSM basis pre-filtered by the light's sigma (the engine then
  runs the basis and pre-filter passes, and binds each light's filtered basis), else it reads the
  light's sigma directly (``reads``);
- ``defines(light_pass)`` and ``bind(light_pass, prog, group)``: its shader defines and uniforms;
- ``twin(...)``: the same visibility in differentiable torch (:func:`viewer.twin.relight.relight`'s ``soft``).
"""

from __future__ import annotations

import importlib
import pkgutil
from abc import ABC, abstractmethod

from viewer.resources import shader_dir

METHODS: dict[str, SoftMethod] = {}  # name -> the method, in the order the files are found (by name)


class SoftMethod(ABC):
    """One way to soften each light's shadow (the module docstring says what a method gives); a method
    without its torch twin cannot be made (registered)."""

    name = ""
    shader = ""  # its GLSL file in shaders/ (a method may give its text otherwise: glsl())
    prefiltered = False

    @property
    def reads(self) -> tuple[str, ...]:
        """What a light's pass reads beside its direction and shadow map: the pre-filtered basis, or its sigma."""
        return ("prefilter",) if self.prefiltered else ("sigma",)

    def glsl(self) -> str:
        return (shader_dir() / self.shader).read_text()

    def defines(self, light_pass) -> dict:
        return {}

    def bind(self, light_pass, prog, group) -> None:
        """Its uniforms for a group of up to four lights (the shadow maps are bound already); a method
        that reads none of its own sets none."""
        return None

    @abstractmethod
    def twin(self, depth, sigma, frames, u, v, d, bias, normal, terms):
        """(N, P) soft visibility in torch: shadow maps ``depth``, the lights' ``sigma`` and ``frames``,
        the receivers' shadow-map coordinates (``u``, ``v``, ``d``), ``bias`` and ``normal`` (P, 3)."""


def register_soft_method(cls):
    """Class decorator: the method ``cls`` (a :class:`SoftMethod`) known by its name."""
    if not cls.name:
        raise ValueError(f"{cls.__name__}: a soft-shadow method needs a name")
    METHODS[cls.name] = cls()
    return cls


def soft_method(name: str) -> SoftMethod:
    """The method called ``name`` (a ValueError names the choices)."""
    if name not in METHODS:
        raise ValueError(f"soft shadows must be one of {', '.join(METHODS)}, got {name!r}")
    return METHODS[name]


def soft_method_names() -> tuple[str, ...]:
    return tuple(METHODS)


for _member in pkgutil.iter_modules(__path__):  # every method in this folder registers itself on import
    importlib.import_module(f"{__name__}.{_member.name}")
