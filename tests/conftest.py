import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
CAMPAIGN_TEST = "test_the_bad_input_campaign_ends_cleanly"
CAMPAIGN = pytest.StashKey[dict]()


def pytest_collection_modifyitems(session, config, items):
    """When the bad-input campaign's test is to run, start the campaign at once, in a fresh Python
    with one job, beside the other tests (which keep one core busy; the campaign alone takes 6
    minutes of two cores): its test, later in the run, waits for it and reads its report."""
    if not any(item.name == CAMPAIGN_TEST for item in items):
        return
    folder = Path(tempfile.mkdtemp(prefix="relight-campaign-"))
    code = ("import sys; from viewer.lab.bench.robustness import run_robustness_benchmark as run; "
            "run(work=sys.argv[1], output=sys.argv[2], jobs=1)")
    with open(folder / "campaign.log", "wb") as log:
        proc = subprocess.Popen([sys.executable, "-c", code, str(folder / "work"), str(folder / "robustness.json")],
                                stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    config.stash[CAMPAIGN] = {"process": proc, "folder": folder}


def pytest_unconfigure(config):
    campaign = config.stash.get(CAMPAIGN, None)
    if campaign is None:
        return
    if campaign["process"].poll() is None:  # the run ended before the campaign's test: the campaign goes with it
        os.killpg(campaign["process"].pid, signal.SIGKILL)
        campaign["process"].wait()
    shutil.rmtree(campaign["folder"], ignore_errors=True)


@pytest.fixture
def campaign(request):
    """The bad-input campaign started with the run: (its exit status, its report's path, its log's text)."""
    started = request.config.stash[CAMPAIGN]
    code = started["process"].wait(timeout=1800)
    return code, started["folder"] / "robustness.json", (started["folder"] / "campaign.log").read_text(errors="replace")


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
