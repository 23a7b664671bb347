"""The fitting methods' names (no torch here: the cache and the command line name them without
fitting); what each does is in :mod:`viewer.lightfit.fit`."""

METHODS = ("instant", "fast", "paper", "median-cut")
DEFAULT_METHOD = "instant"
# lights fitted by these methods serve a request for the key's: slower, and at least as accurate
# on every median of docs/lights.md (a map shipped with `fast` lights needs no instant refit)
AT_LEAST_AS_GOOD = {"instant": ("instant", "fast", "paper")}


def serves(fitted: str, asked: str) -> bool:
    """Whether lights fitted by ``fitted`` answer a request for ``asked`` lights."""
    return fitted in AT_LEAST_AS_GOOD.get(asked, (asked,))

# each method's stages, in order, with their share of the time (viewer.progress.TimeLeft): seconds of
# a 1k map, 16 lights (instant: kiara_1_dawn, fast and paper: studio_small_03), on the 2-core CPU machine,
# 2026-11-25 (median cut reports no stages)
STAGE_SHARES = {
    "instant": {"reference": 0.2, "directions": 0.55, "shadows": 0.35, "sigma": 0.1},
    "fast": {"reference": 1.1, "directions": 2.8, "shadows": 6.0, "sigma": 1.0},
    "paper": {"reference": 1.0, "directions": 16.1, "shadows": 5.6, "sigma": 2.8},  # one thread
}
