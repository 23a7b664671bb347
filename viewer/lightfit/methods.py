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
