"""``relight``: the entry point. It parses (:mod:`viewer.cli.parser`), runs the command
(:mod:`viewer.cli.commands`) and turns what can go wrong into one line: a bad input, a refusal of the
system, an interruption (SIGINT, SIGTERM, SIGHUP: :mod:`viewer.stop_signals`)."""

from __future__ import annotations

import sys

from viewer.cli.parser import build_parser, command_plugins
from viewer.cores import allowed_cores, size_pools, work_threads
from viewer.errors import OUT_OF_MEMORY, InputError, one_line_warning


def main(argv=None) -> int:
    import warnings

    argv = list(sys.argv[1:] if argv is None else argv)
    with warnings.catch_warnings():  # a warning is one line, like an error; the hook is put back after
        warnings.showwarning = one_line_warning
        return _main(argv)


def _main(argv: list) -> int:
    import os

    try:
        os.getcwd()
    except OSError as exc:  # (numpy's MKL and path-less errors came later, deep inside)
        print(f"relight: error: the working folder is gone ({exc.strerror}): cd to a folder that exists and run again",
              file=sys.stderr)
        return 2
    try:
        plugins = command_plugins()
        if argv and argv[0] in plugins:
            return plugins[argv[0]].load()(argv[1:])
        args = build_parser(plugins).parse_args(argv)
        # the cores idle now, not the machine's count (viewer/cores.py); the window's frames are short
        # bursts, not barrier-bound: llvmpipe takes every core allowed there, which measured faster
        # even beside a busy process (docs/viewer.md, "A fluid drag")
        size_pools(work_threads(), allowed_cores() if getattr(args, "window", False) else None)
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
    except MemoryError:  # a limit on the process (ulimit -v) below what the budget checks foresee
        print(f"relight: error: {OUT_OF_MEMORY}", file=sys.stderr)
        return 2
    except Exception as exc:
        if type(exc).__module__.startswith(("moderngl", "_moderngl")):  # the GL driver refused (memory, limits)
            said = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
            print(f"relight: error: OpenGL refused the work ({said}): out of memory (ulimit -v?), or a smaller "
                  "--size / --max-size", file=sys.stderr)
            return 2
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


class _Output:
    """Standard output that never stops the work: a reader gone (``| head -1``: a broken pipe), a
    full device (``>/dev/full``) or a closed descriptor (``>&-``) loses the lines, not the outputs
    being written; the first refusal is said once on stderr when the program ends."""

    def __init__(self, stream):
        self._stream = stream
        self.refused: str | None = None if stream is not None else "closed"

    def write(self, text):
        if self.refused is None:
            try:
                return self._stream.write(text)
            except (OSError, ValueError) as exc:
                self.refused = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        return len(text)

    def flush(self):
        if self.refused is None:
            try:
                self._stream.flush()
            except (OSError, ValueError) as exc:
                self.refused = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__

    def isatty(self) -> bool:
        try:
            return self.refused is None and self._stream.isatty()
        except (OSError, ValueError):
            return False

    def fileno(self):
        if self._stream is None:
            raise OSError("standard output is closed")
        return self._stream.fileno()

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _writable_streams():
    """Descriptors 0-2 held (a closed one, ``>&-``, is given /dev/null: else the next file opened
    takes its number, and what is printed, or captured from native code, lands in it), stdout
    wrapped as :class:`_Output`, a closed stderr written to /dev/null (the exit code still says
    what happened)."""
    import os

    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
    # Python's streams on private copies of descriptors 1 and 2: code that points 1 and 2 elsewhere
    # for a while (imageio.native_output, catching OpenEXR's C++ lines) and is interrupted before it
    # points them back cannot take the program's own lines with it (an interrupted video render
    # exited 130 without its one line, 2 times in 650)
    def private(stream, fd):
        if stream is None:
            return None
        return open(os.dup(fd), "w", buffering=1, encoding=stream.encoding, errors=stream.errors, closefd=True)

    out = _Output(private(sys.stdout, 1))
    sys.stdout = out
    sys.stderr = private(sys.stderr, 2) or open(os.devnull, "w")
    return out


def run() -> None:
    """The ``relight`` program: :func:`main`, then the exit handlers, then out at once. Python's own
    teardown of torch's and MediaPipe's modules took 1.2 s after a photo was inferred (the viewer
    took that long to go after Q); by then every output is written and closed. SIGTERM and SIGHUP
    interrupt like Ctrl-C (the viewer's window sets its own SIGTERM while it is open)."""
    import atexit
    import os
    import signal

    from viewer.stop_signals import keep_stops_raised, route_to_main_thread

    received: list[str] = []  # the stop signals raised in the main thread, by name

    def stop(signum, _frame):  # SIGTERM and SIGHUP end the work as Ctrl-C does: temporary files removed, old outputs kept
        received.append(signal.Signals(signum).name)
        raise KeyboardInterrupt(received[-1])

    out = _writable_streams()
    try:  # a signal from the first handler set on is an interruption, said in one line
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, stop)
        route_to_main_thread()  # never inside native code: llvmpipe's shader compiler crashed on one
        keep_stops_raised()  # nor lost in a native call back into Python
        code = main()
    except KeyboardInterrupt as exc:  # before main's own handling began (the campaign's held-back seed
        # caught one while the signals' thread was starting)
        print(_interrupted(exc), file=sys.stderr)
        code = 130
    except Exception:  # a module's native initialisation that swallowed the interruption into an error of
        # its own with no trace of it (numba: "ImportError: numba._devicearray failed to import" when
        # SIGTERM came during its import): after a stop signal, the stop is what happened
        if not received:
            raise
        print(_interrupted(KeyboardInterrupt(received[0])), file=sys.stderr)
        code = 130
    atexit._run_exitfuncs()  # what registered for the exit (logging's flush, ...) still runs
    out.flush()
    if out.refused is not None and out.refused != "closed":
        print(f"relight: warning: standard output refused its lines ({out.refused}); the outputs were written", file=sys.stderr)
    try:
        sys.stderr.flush()
    except (OSError, ValueError):
        pass
    os._exit(code)


if __name__ == "__main__":
    run()
