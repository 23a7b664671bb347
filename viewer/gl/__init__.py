"""The OpenGL engine: per-light shadow maps, convolutional shadow maps, shading and composite."""

from .context import create_headless_context
from .engine import Engine
from .options import EngineOptions

__all__ = ["Engine", "EngineOptions", "create_headless_context"]
