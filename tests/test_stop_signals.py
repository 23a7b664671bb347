"""Stop signals reach the main thread's Python handler and never interrupt another thread
(viewer.stop_signals): real processes, real signals."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap

CHILD = textwrap.dedent("""
    import json, os, signal, sys, threading, time
    from viewer.stop_signals import route_to_main_thread
    seen = []
    signal.signal(signal.SIGTERM, lambda s, f: seen.append((s, threading.current_thread().name)))
    signal.signal(signal.SIGINT, {sigint})
    route_to_main_thread()
    masks = []
    t = threading.Thread(target=lambda: masks.append(signal.pthread_sigmask(signal.SIG_BLOCK, [])))
    t.start(); t.join()
    os.kill(os.getpid(), signal.{sig})
    start = time.process_time()
    deadline = time.monotonic() + 0.5
    while time.monotonic() < deadline and not seen:
        time.sleep(0.01)
    time.sleep(0.2)
    print(json.dumps({{"seen": seen, "cpu": time.process_time() - start,
                      "blocked": sorted(int(s) for s in masks[0] & {{signal.SIGINT, signal.SIGTERM, signal.SIGHUP}})}}))
""")


def run_child(sig: str, sigint: str = "signal.default_int_handler"):
    proc = subprocess.run([sys.executable, "-c", CHILD.format(sig=sig, sigint=sigint)], capture_output=True,
                          text=True, timeout=60)
    return proc, (json.loads(proc.stdout) if proc.returncode == 0 else None)


def test_a_signal_runs_its_python_handler_on_the_main_thread_and_other_threads_block_it():
    proc, out = run_child("SIGTERM")
    assert proc.returncode == 0, proc.stderr
    assert out["seen"] == [[int(signal.SIGTERM), "MainThread"]]
    assert out["blocked"] == sorted([int(signal.SIGINT), int(signal.SIGTERM), int(signal.SIGHUP)])


def test_an_ignored_signal_is_dropped_without_spinning():
    """SIGINT ignored (a job started in the background): the forwarding thread drops it and does not
    take it again and again."""
    proc, out = run_child("SIGINT", sigint="signal.SIG_IGN")
    assert proc.returncode == 0, proc.stderr
    assert out["seen"] == []
    assert out["cpu"] < 0.2  # CPU seconds over the 0.7 s it waited


def test_a_signal_left_to_its_default_ends_the_process():
    proc, _ = run_child("SIGHUP")
    assert proc.returncode == -signal.SIGHUP, (proc.returncode, proc.stdout, proc.stderr)


HELD = textwrap.dedent("""
    import os, signal, sys, time
    from viewer.stop_signals import held, route_to_main_thread
    def stop(signum, frame):
        raise RuntimeError(f"stopped by {signum}")
    signal.signal(signal.SIGHUP, stop)
    route_to_main_thread()
    done = []
    try:
        with held():
            os.kill(os.getpid(), signal.SIGHUP)
            time.sleep(0.3)  # the forwarding thread hands it on meanwhile
            done.append("block")
        done.append("after")
    except RuntimeError as exc:
        print(done, exc, signal.getsignal(signal.SIGHUP) is stop)
""")


def test_a_signal_within_held_is_delivered_when_the_block_ends():
    """What native code calling back into Python (OpenEXR's stream reads) must not see: the stop comes
    after the block, to the handler that was there, never inside it."""
    proc = subprocess.run([sys.executable, "-c", HELD], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"['block'] stopped by {int(signal.SIGHUP)} True"


SWALLOWED = """
import os, signal, time
import viewer.cli.main as entry

def work(argv=None):
    os.kill(os.getpid(), signal.SIGTERM)
    try:
        time.sleep(5)  # the signal arrives here, as a KeyboardInterrupt
    except KeyboardInterrupt:
        pass  # native initialisation code that swallows it ...
    raise ImportError("numba._devicearray failed to import")  # ... into an error of its own, with no trace of it

entry.main = work
entry.run()
"""


def test_a_stop_swallowed_into_another_error_is_said_as_the_stop():
    """SIGTERM during a module's native initialisation (numba's import: "failed to import") ends the
    program as the stop it was: one line, exit 130, no traceback."""
    proc = subprocess.run([sys.executable, "-c", SWALLOWED], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 130 and proc.stderr.strip() == "relight: interrupted (SIGTERM)", proc.stderr


IN_CALLBACK = """
import ctypes, os, signal, time
import viewer.cli.main as entry

def work(argv=None):
    def callback():  # a native library's call back into Python (llvmlite's object cache, numba compiling)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the stop arrives here, inside the callback: ctypes cannot let it out
    ctypes.CFUNCTYPE(None)(callback)()
    time.sleep(5)  # the work goes on after the callback: the stop must come here
    print("finished")
    return 0

entry.main = work
entry.run()
"""


def test_a_stop_raised_inside_a_native_callback_is_not_lost():
    """SIGTERM while native code runs a Python callback: the stop is not swallowed (no "Exception ignored",
    no finished work with exit 0): one line, exit 130."""
    proc = subprocess.run([sys.executable, "-c", IN_CALLBACK], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 130 and proc.stderr.strip() == "relight: interrupted (SIGTERM)", proc.stderr
    assert "finished" not in proc.stdout
