"""``relight``: the entry point. It parses (:mod:`viewer.cli.parser`), runs the command
(:mod:`viewer.cli.commands`) and turns what can go wrong into one line: a bad input, a refusal of the
system, an interruption (SIGINT, SIGTERM, SIGHUP: :mod:`viewer.stop_signals`)."""

from __future__ import annotations

import sys

from .parser import build_parser, command_plugins
from ..cores import size_pools, work_threads
from ..errors import InputError


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"relight: warning: {message}", file=sys.stderr if file is None else file, flush=True)


def main(argv=None) -> int:
    import warnings

    argv = list(sys.argv[1:] if argv is None else argv)
    with warnings.catch_warnings():  # a warning is one line, like an error; the hook is put back after
        warnings.showwarning = _one_line_warning
        return _main(argv)


def _main(argv: list) -> int:
    try:
        plugins = command_plugins()
        if argv and argv[0] in plugins:
            return plugins[argv[0]].load()(argv[1:])
        args = build_parser(plugins).parse_args(argv)
        size_pools(work_threads())  # the cores idle now, not the machine's count (viewer/cores.py)
        return args.func(args)
    except InputError as exc:
        print(f"relight: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the system refused a read or a write the checks could not foresee
        where = exc.filename if exc.filename is not None else None
        print(f"relight: error: {InputError(where, exc.strerror or str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(_interrupted(exc), file=sys.stderr)
        return 130
    except Exception as exc:
        # native code that runs Python code (a module's initialisation) may turn the interruption
        # into its own exception ("ImportError: initialization failed", caused by the KeyboardInterrupt)
        cause = _interruption(exc)
        if cause is None:
            raise
        print(_interrupted(cause), file=sys.stderr)
        return 130


def _interruption(exc: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt an exception was raised from or while handling, if any."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _interrupted(exc: KeyboardInterrupt) -> str:
    """The one line for an interruption: Ctrl-C, or the signal :func:`run` turned into one (its name
    in the exception), and what the work left where (its notes)."""
    by = f" ({exc.args[0]})" if exc.args and isinstance(exc.args[0], str) and exc.args[0].startswith("SIG") else ""
    return f"relight: interrupted{by}" + "".join(f"; {note}" for note in getattr(exc, "__notes__", ()))


def run() -> None:
    """The ``relight`` program: :func:`main`, then the exit handlers, then out at once. Python's own
    teardown of torch's and MediaPipe's modules took 1.2 s after a photo was inferred (the viewer
    took that long to go after Q); by then every output is written and closed. SIGTERM and SIGHUP
    interrupt like Ctrl-C (the viewer's window sets its own SIGTERM while it is open)."""
    import atexit
    import os
    import signal

    from ..stop_signals import route_to_main_thread

    def stop(signum, _frame):  # SIGTERM and SIGHUP end the work as Ctrl-C does: temporary files removed, old outputs kept
        raise KeyboardInterrupt(signal.Signals(signum).name)

    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, stop)
    route_to_main_thread()  # never inside native code: llvmpipe's shader compiler crashed on one
    try:
        code = main()
    except KeyboardInterrupt as exc:  # before main's own handling began
        print(_interrupted(exc), file=sys.stderr)
        code = 130
    atexit._run_exitfuncs()  # what registered for the exit (logging's flush, ...) still runs
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


if __name__ == "__main__":
    run()
