"""A campaign case, how it runs (the real command line in its own process, its peak memory taken
from the kernel's accounting of that process) and how it is judged."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

TIMEOUT = 180.0
# lines a command may print besides its one error line: progress (bars, infer's stages, the fit's
# bars), warnings, and argparse's usage above its error
ALLOWED_PREFIXES = ("  ", "fitting ", "relight: warning:", "usage: ")


@dataclass
class Case:
    group: str
    name: str
    args: list[str]
    expect: str  # "ok", "black" or "warned" (ok, with a warning line), or "error"
    output: str | None = None  # the -o target (absent or unchanged on an error)
    cache: str | None = None  # its own light cache (default: the campaign's)
    upright: tuple | None = None  # an inferred bundle's frame must come out this size (not sideways)
    watch: list[str] = field(default_factory=list)  # more files that must come out unchanged (a user's)
    not_said: str | None = None  # words its output must not hold (e.g. stale lights used)
    said: str | None = None  # words its stderr must hold (a warning the case is about)
    result: dict = field(default_factory=dict)


@dataclass
class Scenario:
    """A case that is more than one command: processes killed at random moments, a full disk, two
    writers racing. ``run(work)`` returns its problems (empty: clean), the processes' peak (KB) and
    the exit code of the process the case is about."""

    group: str
    name: str
    run: Callable[[Path], tuple[list[str], int, int | None]]
    result: dict = field(default_factory=dict)


def exists(path) -> bool:
    try:
        return Path(path).exists()
    except OSError:  # a name the system refuses (too long): nothing is there
        return False


def digest(path: Path) -> str | None:
    """A file's or folder's content hash; a pipe or a device is named, never read (it could block or never end)."""
    if not exists(path):
        return None
    if path.is_symlink() and not path.exists():
        return f"link:{os.readlink(path)}"
    if not path.is_dir() and not path.is_file():
        return f"special:{path.resolve()}"
    if path.is_dir():
        return "dir:" + ",".join(sorted(os.fsdecode(p.name) + ":" + (digest(p) or "") for p in path.iterdir()))
    return hashlib.sha256(path.read_bytes()).hexdigest()


def truncations(data: bytes, name: str, write):
    """Files cut at several points (and emptied)."""
    for frac in (0.0, 0.01, 0.1, 0.5, 0.9):
        cut = int(len(data) * frac)
        yield f"{name} truncated to {cut} bytes", write(f"trunc{int(frac * 100)}_{name}", data[:cut])


# Runs ``relight ARGS`` as its child and writes the child's peak resident KB to a file. The peak of
# a process forked straight from the campaign would count the campaign's own memory (Linux carries
# the parent's high-water mark through fork and exec); forked from this small process it does not.
# Signals sent to it are passed on; the child's exit code, or its signal, is its own.
PEAK_WRAPPER = """
import json, os, resource, signal, sys
pid = os.fork()
if pid == 0:
    setup = json.loads(sys.argv[2])  # (ChildSetup: done here, in one thread, not in a threaded parent's preexec_fn)
    for name, value in setup["rlimits"].items():
        resource.setrlimit(getattr(resource, name), (value, value))
    if setup["full_stdout"]:
        full = os.open("/dev/full", os.O_WRONLY)
        os.dup2(full, 1)
        os.close(full)
    for fd in setup["close"]:
        os.close(fd)
    os.execv(sys.executable, [sys.executable, "-m", "viewer.cli.main", *sys.argv[3:]])
def forward(n, f):
    try:
        os.kill(pid, n)
    except ProcessLookupError:  # it ended (and was waited for) as the signal came: its own exit stands
        pass
for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
    signal.signal(s, forward)
signal.pthread_sigmask(signal.SIG_UNBLOCK, (signal.SIGINT, signal.SIGTERM, signal.SIGHUP))  # (relight blocks them)
while True:
    try:
        _, status, usage = os.wait4(pid, 0)
        break
    except InterruptedError:
        pass
with open(sys.argv[1], "w") as f:
    f.write(str(usage.ru_maxrss))
if os.WIFSIGNALED(status):
    signal.signal(os.WTERMSIG(status), signal.SIG_DFL)
    os.kill(os.getpid(), os.WTERMSIG(status))
os._exit(os.WEXITSTATUS(status))
"""


@dataclass(frozen=True)
class ChildSetup:
    """What the command's process is given before it starts (by :data:`PEAK_WRAPPER`, single-threaded:
    a ``preexec_fn`` in the campaign's threaded process can deadlock the fork, and did): resource
    limits (``RLIMIT_AS``: bytes), its stdout a full device, descriptors closed."""

    rlimits: dict = field(default_factory=dict)
    full_stdout: bool = False
    close: tuple = ()

    def to_json(self) -> str:
        return json.dumps({"rlimits": self.rlimits, "full_stdout": self.full_stdout, "close": list(self.close)})


def start_command(args: list, peak_file: Path, env: dict | None = None, setup: ChildSetup = ChildSetup(),
                  **popen) -> subprocess.Popen:
    """``relight ARGS`` started under :data:`PEAK_WRAPPER` (its peak goes to ``peak_file``; ``setup``
    done in the command's process before it starts)."""
    return subprocess.Popen([sys.executable, "-c", PEAK_WRAPPER, str(peak_file), setup.to_json(), *map(os.fsdecode, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, start_new_session=True, **popen)


def peak_of(peak_file: Path) -> int:
    try:
        return int(peak_file.read_text())
    except (OSError, ValueError):
        return 0


def run_command(args: list, env: dict | None = None, timeout: float = TIMEOUT, setup: ChildSetup = ChildSetup()):
    """``relight ARGS`` in its own process: (exit code or None on a timeout, stdout, stderr, seconds,
    peak resident KB of that one process)."""
    import signal
    import tempfile

    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="relight-peak-") as tmp:
        peak_file = Path(tmp) / "peak"
        proc = start_command(args, peak_file, env, setup)
        try:
            out, err = proc.communicate(timeout=timeout)
            code = proc.returncode
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, err = proc.communicate()
            code = None
        peak = peak_of(peak_file)
    return (code, out.decode("utf-8", "replace"), err.decode("utf-8", "replace"), time.perf_counter() - start, peak)


def said_lines(err: str) -> list[str]:
    """A command's stderr lines, progress bars left out."""
    return [line for line in err.splitlines() if line.strip() and "%|" not in line]


def judge(case: Case, code: int, err: str, lines: list[str], before: dict, out: str = "") -> list[str]:
    problems = []
    if "Traceback" in err:
        problems.append("traceback")
    if case.not_said and case.not_said in out + err:
        problems.append(f"said {case.not_said!r}")
    if case.said and case.said not in err:
        problems.append(f"did not say {case.said!r}")
    if case.expect == "error":
        if code != 2:
            problems.append(f"exit {code}, expected 2")
        errors = [line for line in lines if "error:" in line]
        if len(errors) != 1:
            problems.append(f"{len(errors)} error lines")
        others = [line for line in lines if "error:" not in line and not line.startswith(ALLOWED_PREFIXES)]
        if others:  # a library's own words (OpenEXR's C++ lines) printed beside ours
            problems.append(f"a line besides the error: {others[0][:120]!r}")
        if case.output is not None and digest(Path(case.output)) != before.get(case.output):
            problems.append("the -o target was written")
    else:
        if code != 0:
            problems.append(f"exit {code}, expected 0")
        elif case.upright is not None:
            frame = json.loads((Path(case.output) / "scene.json").read_text())["frame"]
            if abs(frame["width"] - case.upright[0]) > 1 or abs(frame["height"] - case.upright[1]) > 1:
                problems.append(f"frame {frame['width']}x{frame['height']}, expected {case.upright[0]}x{case.upright[1]} upright")
        elif case.output and case.output.lower().endswith(".png"):
            from viewer.files.imageio import read_png

            img = read_png(case.output)
            bright = float(img[..., :3].mean())
            if case.expect == "ok" and bright < 0.01:
                problems.append("black output")
            if case.expect in ("black", "warned") and not any("warning" in line for line in lines):
                problems.append(f"{'black' if case.expect == 'black' else 'a white person'} without a warning")
    changed = [p for p, d in before.items() if p != case.output and digest(Path(p)) != d]
    if changed:
        problems.append(f"input changed: {changed[:2]}")
    return problems


def inputs(case: Case) -> list[str]:
    """The files and folders a case reads, and the user's files beside its outputs (watched: they
    must come out unchanged)."""
    return [a for a in case.args if a != case.output and os.path.sep in a and exists(a)] + case.watch


def run_case(case: Case, work: Path) -> dict:
    watched = {p: digest(Path(p)) for p in inputs(case) + ([case.output] if case.output else [])}
    env = {**os.environ, "RELIGHT_CACHE": case.cache or str(work / "cache")}
    code, out, err, seconds, peak = run_command(case.args, env)
    if code is None:
        return {"exit": None, "seconds": TIMEOUT, "clean": False, "problems": [f"no answer in {TIMEOUT:.0f} s"],
                "last_line": "", "peak_mb": round(peak / 1024)}
    lines = said_lines(err)
    problems = judge(case, code, err, lines, watched, out)
    return {"exit": code, "seconds": round(seconds, 2), "clean": not problems, "problems": problems,
            "last_line": lines[-1][:300] if lines else "", "peak_mb": round(peak / 1024)}


def run_scenario(scenario: Scenario, work: Path) -> dict:
    start = time.perf_counter()
    try:
        problems, peak, code = scenario.run(work)
    except Exception as exc:  # the scenario's own failure is a problem, reported, not a crash of the campaign
        problems, peak, code = [f"the scenario failed: {type(exc).__name__}: {exc}"], 0, None
    return {"exit": code, "seconds": round(time.perf_counter() - start, 2), "clean": not problems, "problems": problems,
            "last_line": "", "peak_mb": round(peak / 1024)}
