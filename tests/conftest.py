import inspect
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

TESTS = Path(__file__).resolve().parent
SHARED_DATA = TESTS.parent.parent / "shared" / "data"
CAMPAIGN_TEST = "test_the_bad_input_campaign_ends_cleanly"
CAMPAIGN_PARTS = 2  # the campaign in halves, one on each worker of ``make test``
CAMPAIGN = pytest.StashKey[dict]()  # part -> the campaign's process and folder


@pytest.hookimpl(tryfirst=True)  # (before pytest-xdist reads the groups)
def pytest_collection_modifyitems(session, config, items):
    """The bad-input campaign's tests first, and the tests that share what is expensive to make on one
    worker (``make test`` runs two, pytest-xdist's ``--dist loadgroup``): those of a module that share
    a fixture made once per module, and those that share the session's dataset and networks. Under
    xdist the largest groups go first (``--no-loadscope-reorder`` keeps this order), so no worker is
    left with a large group alone at the end.

    The campaign (407 cases, each a fresh ``relight``: 11 minutes of one core) runs in two halves, each
    in a fresh Python with one job. Under xdist each half's test is the first its worker runs and
    starts it there; in one process both start at once, beside the other tests, and their tests, later
    in the run, wait for them and read their reports."""
    groups = {item: _shared_fixture(item) for item in items}
    for item, group in groups.items():
        if group is not None:
            item.add_marker(pytest.mark.xdist_group(group))
    campaign = [item for item in items if item.originalname == CAMPAIGN_TEST]
    config.stash[CAMPAIGN] = {}
    if os.environ.get("PYTEST_XDIST_WORKER"):  # the campaign, then the largest groups: the workers end together
        size = Counter(groups.values())
        items.sort(key=lambda item: (item not in campaign, groups[item] is None, -size[groups[item]]))
        return
    for item in campaign:
        part = item.callspec.params["part"]
        config.stash[CAMPAIGN][part] = _start_campaign(part)


def _shared_fixture(item) -> str | None:
    """The group of the tests that share an expensive fixture with ``item``: the session's (any but the
    GL context, which each worker makes in a moment), else the module's; None when it shares none."""
    defs = [item._fixtureinfo.name2fixturedefs.get(name, (None,))[-1] for name in item.fixturenames]
    ours = [d for d in defs if d is not None and d.argname != "ctx" and Path(inspect.getfile(d.func)).parent == TESTS]
    scopes = {d.scope for d in ours}
    if "session" in scopes:
        return "session data"
    return item.module.__name__ if "module" in scopes else None


def _start_campaign(part: int) -> dict:
    folder = Path(tempfile.mkdtemp(prefix="relight-campaign-"))
    code = ("import sys; from viewer.lab.bench.robustness import run_robustness_benchmark as run; "
            f"run(work=sys.argv[1], output=sys.argv[2], jobs=1, part=({part}, {CAMPAIGN_PARTS}))")
    with open(folder / "campaign.log", "wb") as log:
        proc = subprocess.Popen([sys.executable, "-c", code, str(folder / "work"), str(folder / "robustness.json")],
                                stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    return {"process": proc, "folder": folder}


def pytest_unconfigure(config):
    for campaign in config.stash.get(CAMPAIGN, {}).values():
        if campaign["process"].poll() is None:  # the run ended before the campaign's test: the campaign goes with it
            os.killpg(campaign["process"].pid, signal.SIGKILL)
            campaign["process"].wait()
        shutil.rmtree(campaign["folder"], ignore_errors=True)


@pytest.fixture(params=range(CAMPAIGN_PARTS))
def part(request):
    """Which half of the bad-input campaign: (k, the number of parts), as its report says it."""
    return request.param, CAMPAIGN_PARTS


@pytest.fixture
def campaign(request, part):
    """The bad-input campaign's ``part``, started with the run or now: (its exit status, its report's
    path, its log's text)."""
    started, k = request.config.stash[CAMPAIGN], part[0]
    if k not in started:
        started[k] = _start_campaign(k)
    code = started[k]["process"].wait(timeout=1800)
    folder = started[k]["folder"]
    return code, folder / "robustness.json", (folder / "campaign.log").read_text(errors="replace")


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
