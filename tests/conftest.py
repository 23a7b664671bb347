import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session")
def ctx():
    """One real headless OpenGL context (EGL; Mesa llvmpipe on CI) for the whole session."""
    from viewer.gl import create_headless_context

    return create_headless_context()


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """A three-person dataset at 64^2 made by the command line in two shards (people 0, 2 and 1),
    one lighting each, for the dataset, loader and training tests. Returns (dir, the arguments)."""
    from viewer.cli.main import main

    out = tmp_path_factory.mktemp("dataset")
    args = ["dataset", "make", "--out", str(out), "--count", "3", "--res", "64", "--pool", "1", "--spp", "16", "--lightings", "1"]
    assert main(args + ["--shard", "0/2"]) == 0
    assert main(args + ["--shard", "1/2"]) == 0
    return out, args


@pytest.fixture(scope="session")
def tiny_networks(tiny_dataset, tmp_path_factory):
    """The three networks trained for one epoch on the tiny dataset (small sizes): real weights and
    cards for the inference and refinement tests. Returns their folder."""
    from viewer.cli.main import main

    out = tmp_path_factory.mktemp("networks")
    for net in ("inverse", "depth", "refine"):
        assert main(["train", net, "--data", str(tiny_dataset[0]), "--out", str(out), "--res", "64", "--levels", "3",
                     "--width", "8", "--batch", "2", "--epochs", "1"]) == 0
    return out


def render_by_units(eng, before, on_call=lambda calls: None, limit: int = 200) -> int:
    """Budgeted renders of one unit of work each until the engine's frame is complete; until then
    its display must still be ``before`` (never a half-updated frame). ``on_call(calls)`` runs after
    each incomplete call. Returns the number of calls."""
    calls = 0
    while True:
        eng.render(budget=0.0)
        calls += 1
        if eng.complete:
            return calls
        np.testing.assert_array_equal(eng.output.read_display(), before)
        on_call(calls)
        assert calls < limit
