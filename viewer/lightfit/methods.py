"""The fitting methods' names (no torch here: the cache and the command line name them without
fitting); what each does is in :mod:`viewer.lightfit.fit`."""

METHODS = ("fast", "paper", "median-cut")
DEFAULT_METHOD = "fast"
