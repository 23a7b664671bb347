"""The one exception type users see: a clear message naming the file and the problem."""


def one_line(text: str) -> str:
    """``text`` with control characters (a newline in a file name) shown escaped: a message stays one
    line. A name's bytes that are not UTF-8 (kept by Python as surrogates) are shown as ``\\xff``."""
    text = str(text).encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


OUT_OF_MEMORY = ("out of memory (is the process's memory limited, ulimit -v?): give it more, or a smaller "
                 "--max-size / --size")  # a MemoryError's one line: the limit below what the budget checks foresee


class InputError(ValueError):
    """Bad user input (a file or a parameter). The message names the file and what is wrong, on one line."""

    def __init__(self, path, problem: str):
        self.path = one_line(path) if path is not None else None
        self.problem = one_line(problem)
        super().__init__(f"{self.path}: {self.problem}" if self.path else self.problem)


class NoPersonError(InputError):
    """No person to relight in a picture (none found, an empty mask, too small): a photo is refused
    with it; a clip's frame with it shows only the new background."""


def task_error(exc: Exception) -> str:
    """A failed task's one line: the user's own mistake as it is said (InputError), anything else as
    its type and the first line of its message."""
    if isinstance(exc, InputError):
        return str(exc)
    text = f"{type(exc).__name__}: {exc}".strip().splitlines()
    return text[0] if text else type(exc).__name__


def one_line_warning(message, category, filename, lineno, file=None, line=None):
    """``warnings.showwarning`` for relight's processes: a warning is one line, like an error."""
    import sys

    print(f"relight: warning: {message}", file=sys.stderr if file is None else file, flush=True)
