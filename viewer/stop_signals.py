"""SIGINT, SIGTERM and SIGHUP reach relight's Python code, never its native code.

The kernel runs a signal's handler on a thread it picks, in the middle of whatever that thread is
doing. Python's own C handler only notes the signal, yet llvmpipe's shader compiler (LLVM) crashed
with SIGSEGV when SIGTERM arrived while it compiled a program: 1 render in about 100 signalled at a
random moment beside two busy processes, with interrupted system calls set to restart.

So ``relight`` blocks these signals in every thread (threads started later, llvmpipe's, torch's and
the video encoder's, inherit the mask) and one daemon thread takes them with ``sigwait`` and hands
each to the main thread as if it had arrived there (``_thread.interrupt_main``): the Python handler
runs between two bytecodes of the main thread, as it did, and no native code is ever interrupted.
A main thread blocked in a wait sees the signal when the wait ends (the window's loop waits at most
0.25 s). Processes started by relight inherit the mask; the viewer's worker child ends with its
standard input or when the window kills it, never on a signal.
"""

from __future__ import annotations

import _thread
import contextlib
import signal
import sys
import threading

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
AGAIN_AFTER = 0.02  # seconds: a stop lost in a native callback is delivered again this long after


def route_to_main_thread() -> None:
    """Block :data:`STOP_SIGNALS` in this process's threads and forward them to the main thread's
    Python handlers from a daemon thread. Called once, from the main thread, before any other
    thread starts (relight's entry point, :func:`viewer.cli.main.run`)."""
    if threading.current_thread() is not threading.main_thread():
        raise RuntimeError("stop signals are routed from the main thread")
    signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    threading.Thread(target=_forward, name="stop-signals", daemon=True).start()


def keep_stops_raised() -> None:
    """A stop's ``KeyboardInterrupt`` raised inside native code's call back into Python (a ctypes
    callback: llvmlite's object cache while numba compiles during an infer) cannot leave it: Python
    prints it as "Exception ignored" and the work goes on as if no stop had come (the robustness
    campaign's SIGTERM at 65 % of an infer once ended with exit 0 and that traceback). Such a stop is
    delivered again from a thread (:func:`deliver`, ``AGAIN_AFTER`` later) to land between the main thread's next bytecodes
    outside the callback; nothing is printed for it. Other unraisable exceptions are reported as before."""
    previous = sys.unraisablehook

    def hook(unraisable):
        exc = unraisable.exc_value
        if not isinstance(exc, KeyboardInterrupt):
            previous(unraisable)
            return
        name = exc.args[0] if exc.args and isinstance(exc.args[0], str) else ""  # the stop handler's: the signal's name
        signum = signal.Signals[name] if name in signal.Signals.__members__ else signal.SIGINT
        again = threading.Timer(AGAIN_AFTER, deliver, (signum,))  # (after the hook has returned: not raised inside it)
        again.daemon = True
        again.start()

    sys.unraisablehook = hook


def _forward() -> None:
    while True:
        deliver(signal.sigwait(STOP_SIGNALS))


def deliver(signum: int) -> None:
    """``signum`` to the main thread's handler as if it had just arrived: a Python handler runs
    between the main thread's next two bytecodes; an ignored signal is dropped; one left to its
    default action ends the process, as the kernel would have."""
    handler = signal.getsignal(signum)
    if callable(handler):
        _thread.interrupt_main(signum)
    elif handler == signal.SIG_DFL:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, [signum])
        signal.raise_signal(signum)


@contextlib.contextmanager
def held():
    """Within the block the stop signals are only noted; the first one noted is delivered when the block
    ends (:func:`deliver`). For native code that calls back into Python (OpenEXR reading and writing a
    Python stream): a handler's exception raised inside such a callback is swallowed by the native code
    and comes back as a failure of its own ("cannot read EXR (initialization failed)") instead of the
    stop it was. Also for steps that must not be cut in two (files replaced together). Outside the main
    thread, where handlers cannot be set, the block runs as it is."""
    caught: list[int] = []
    on_main = threading.current_thread() is threading.main_thread()
    signals = [sig for sig in STOP_SIGNALS if on_main and signal.getsignal(sig) is not None]  # handlers Python can put back
    previous = {sig: signal.signal(sig, lambda signum, _frame: caught.append(signum)) for sig in signals}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if caught:
        deliver(caught[0])


def die_with_parent() -> None:
    """prctl(PR_SET_PDEATHSIG, SIGKILL): Linux ends this process when its parent ends."""
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):
        pass  # not Linux: the pipe's end is seen at the next task
