"""The OpenGL engine: per-light shadow maps, convolutional shadow maps, shading and composite."""

from viewer.gl.context import create_headless_context
from viewer.gl.engine import Engine
from viewer.gl.options import EngineOptions

__all__ = ["Engine", "EngineOptions", "create_headless_context"]
