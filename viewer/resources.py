"""Where shaders and bundled assets live, from a source checkout or an installed wheel.

In the source tree they are the top-level ``shaders/`` and ``assets/`` folders; an installed
wheel carries the same folders as ``viewer/shaders`` and ``viewer/assets`` (see pyproject.toml).
"""

from __future__ import annotations

from pathlib import Path

_PKG = Path(__file__).resolve().parent


def _find(name: str) -> Path:
    for candidate in (_PKG / name, _PKG.parent / name):  # installed wheel first, then a checkout
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"cannot find the '{name}' folder next to {_PKG}")


def shader_dir() -> Path:
    return _find("shaders")


def asset_dir() -> Path:
    return _find("assets")


def sample_scene_dir() -> Path:
    return asset_dir() / "sample_scene"


def network_dir() -> Path:
    """The shipped network weights (``<net>.safetensors`` with their ``<net>.json`` cards)."""
    return asset_dir() / "networks"
