import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session")
def ctx():
    """One real headless OpenGL context (EGL; Mesa llvmpipe on CI) for the whole session."""
    from viewer.gl import create_headless_context

    return create_headless_context()
