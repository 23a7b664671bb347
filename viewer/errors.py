"""The one exception type users see: a clear message naming the file and the problem."""


class InputError(ValueError):
    """Bad user input (a file or a parameter). The message names the file and what is wrong."""

    def __init__(self, path, problem: str):
        self.path = str(path) if path is not None else None
        self.problem = problem
        super().__init__(f"{self.path}: {problem}" if self.path else problem)
