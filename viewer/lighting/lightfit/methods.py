"""The fitting methods' names (no torch here: the cache and the command line name them without
fitting); what each does is in :mod:`viewer.lighting.lightfit.fit`."""

METHODS = ("instant", "fast", "paper", "median-cut")
DEFAULT_METHOD = "instant"
# lights fitted by these methods serve a request for the key's: slower, and at least as accurate
# on every median of docs/lights.md (a map shipped with `fast` lights needs no instant refit; `paper`'s
# sigmas come from its own search, which the map's sizes beat on people: docs/lights.md)
AT_LEAST_AS_GOOD = {"instant": ("instant", "fast")}


# the paper's method holds every light's soft visibility at each sigma of its Step 3: its time and
# memory grow with the lights (measured with the same table in the fast method before it took its
# sigmas from the map, 1k map: 21 s / 1.6 GB at 32 lights, 43 s / 2.6 GB at 64, 90 s / 4.7 GB at 128)
MAX_LIGHTS_FOR = {"paper": 64}


def check_light_count(method: str, n: int, source=None) -> None:
    """Refuse in one line a light count a method does not fit (its stated limit)."""
    from viewer.errors import InputError

    limit = MAX_LIGHTS_FOR.get(method)
    if limit is not None and n > limit:
        raise InputError(source, f"--method {method} fits at most {limit} lights (its time and memory grow with "
                                 f"each light), got {n}: use --method instant for more")


def serves(fitted: str, asked: str) -> bool:
    """Whether lights fitted by ``fitted`` answer a request for ``asked`` lights."""
    return fitted in AT_LEAST_AS_GOOD.get(asked, (asked,))

# each method's stages, in order, with their share of the time (viewer.progress.TimeLeft): seconds of
# a 1k map, 16 lights (instant and fast: 2026-11-26, three maps; paper:
# studio_small_03, 2026-11-25), on the 2-core CPU machine (median cut reports no stages)
STAGE_SHARES = {
    "instant": {"reference": 0.08, "directions": 0.38},
    "fast": {"reference": 0.41, "directions": 2.42},
    "paper": {"reference": 1.0, "directions": 16.1, "shadows": 5.6, "sigma": 2.8},  # one thread
}
