"""Cases of more than one command: SIGTERM and SIGHUP at random moments of a frame's and a video's
write, a full disk, two writers racing for one output. Each returns its problems (empty: clean),
the largest peak of its processes and the exit code of the one the case is about."""

from __future__ import annotations

import os
import random
import shutil
import signal
import subprocess
import time
from functools import partial
from pathlib import Path

from viewer.lab.bench.robustness.case import ChildSetup, Scenario, peak_of, run_command, start_command
from viewer.resources import asset_dir, sample_scene_dir

SCENE = sample_scene_dir()
LIGHTS = asset_dir() / "envmaps" / "venice_sunset_256.lights.json"
PHOTO = asset_dir() / "photos" / "underpass.jpg"
MASK = asset_dir() / "photos" / "underpass.mask.png"


def scenarios(seed: int = 33) -> list[Scenario]:
    rng = random.Random(seed)
    cases = []
    for sig in (signal.SIGTERM, signal.SIGHUP):
        for _ in range(3):
            fraction = rng.uniform(0.1, 1.0)
            cases.append(Scenario("interrupted outputs", f"{sig.name} at {fraction:.0%} of a frame's render",
                                  partial(_signal_a_frame, sig, fraction)))
        fraction = rng.uniform(0.3, 0.9)
        cases.append(Scenario("interrupted outputs", f"{sig.name} at {fraction:.0%} of a video's render",
                              partial(_signal_a_video, sig, fraction)))
    for k in range(5):
        sig, fraction = (signal.SIGTERM, signal.SIGINT)[k % 2], rng.uniform(0.3, 1.0)
        cases.append(Scenario("interrupted bundles (issue 43)", f"{sig.name} at {fraction:.0%} of an infer over an earlier bundle",
                              partial(_signal_an_infer, sig, fraction)))
    for stem in (rng.sample(["..", ".", ".hidden", "manifest.jsonl", "contact-sheet", "...", ".relight-batch"], 5)):
        cases.append(Scenario("a batch's names (issue 43)", f"a photo named {stem}.jpg, run twice into its own folder",
                              partial(_batch_names, stem)))
    for how in (("stdout closed", "stderr closed", "stdout a full device", "every stream closed", "stdin closed")):
        cases.append(Scenario("closed and full streams (issue 43)", how, partial(_streams, how)))
    for k in range(5):
        version = rng.choice(["2.1", "3.0", "3.3", "1.5", "4.0", "4.5", "4.6"])
        cases.append(Scenario("the process's surroundings (issue 43)", f"MESA_GL_VERSION_OVERRIDE={version} ({k + 1})",
                              partial(_surroundings, "gl", f"{version}", k)))
    for k in range(3):
        cases.append(Scenario("the process's surroundings (issue 43)", f"a deleted working folder ({k + 1})",
                              partial(_surroundings, "cwd", "", k)))
    for k in range(5):
        limit = rng.randint(450, 1400)
        cases.append(Scenario("the process's surroundings (issue 43)", f"ulimit -v {limit} MB ({k + 1})",
                              partial(_memory_limit, limit, k)))
    cases.append(Scenario("interrupted outputs", "a full disk while a frame is written", _full_disk))
    cases.append(Scenario("read-only folders", "fit-lights --plot beside a map in a read-only folder", _read_only_map))
    for k in range(2):
        cases.append(Scenario("two writers", f"two infer into one -o at once ({k + 1})", partial(_two_writers, k)))
    return cases


def _start(args, folder: Path):
    """``relight ARGS`` started in ``folder``; :func:`_reap` ends it."""
    proc = start_command(args, folder.parent / f".peak_{folder.name}_{time.monotonic_ns()}", cwd=folder)
    proc.peak_file = Path(proc.args[3])
    return proc


def _reap(proc) -> tuple[int, str, int]:
    """Exit code, stderr and peak KB of a process started by :func:`_start`."""
    _, err = proc.communicate()
    peak = peak_of(proc.peak_file)
    proc.peak_file.unlink(missing_ok=True)
    return proc.returncode, err.decode("utf-8", "replace"), peak


def _leftovers(folder: Path, keep: set) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


def _interrupted(sig, code: int, err: str) -> list[str]:
    """What an interrupted command may end with: done before the signal (0), the one interrupted line
    (130), or ended by it while Python itself was starting, before anything was written."""
    lines = err.strip().splitlines()
    said = "relight: interrupted" if sig == signal.SIGINT else f"relight: interrupted ({sig.name})"  # Ctrl-C has no name
    if code == 130:
        return [] if lines and lines[-1].startswith(said) and "Traceback" not in err \
            else [f"exit 130 without the one line: {err[-200:]!r}"]
    return [] if code in (0, -sig) and "Traceback" not in err else [f"exit {code}: {err[-200:]!r}"]


def _signal_a_frame(sig, fraction: float, work: Path):
    folder = work / "scenarios" / f"frame_{sig.name}_{fraction:.3f}"
    folder.mkdir(parents=True)
    args = ("render", SCENE, LIGHTS, "--size", "128", "-o", folder / "x.png")
    code, _, err, seconds, peak = run_command([*args, "--yaw", "90"])  # its time, and the old outputs
    if code != 0:
        return [f"the first render failed: {err[-200:]}"], peak, code
    old = {p.name: p.read_bytes() for p in folder.iterdir()}
    proc = _start([*args, "--yaw", "200"], folder)
    time.sleep(seconds * fraction)
    proc.send_signal(sig)
    code, err, peak2 = _reap(proc)
    problems = _interrupted(sig, code, err)
    now = {p.name: p.read_bytes() for p in folder.iterdir()}
    if set(now) != set(old):
        problems.append(f"files left: {_leftovers(folder, set(old))}")
    elif (now["x.png"] == old["x.png"]) != (now["x.exr"] == old["x.exr"]):
        problems.append("a new PNG beside the old EXR (or the other way round)")
    return problems, max(peak, peak2), code


def _signal_a_video(sig, fraction: float, work: Path):
    folder = work / "scenarios" / f"video_{sig.name}_{fraction:.3f}"
    folder.mkdir(parents=True)
    video = folder / "v.mp4"
    code, _, err, seconds, peak = run_command(["render", SCENE, LIGHTS, "--size", "96", "--frames", "12", "-o", video])
    if code != 0:
        return [f"the first video failed: {err[-200:]}"], peak, code
    old = video.read_bytes()
    proc = _start(["render", SCENE, LIGHTS, "--size", "96", "--frames", "12", "--yaw", "45", "-o", video], folder)
    time.sleep(seconds * fraction)
    proc.send_signal(sig)
    code, err, peak2 = _reap(proc)
    problems = _interrupted(sig, code, err)
    if code != 0 and video.read_bytes() != old:
        problems.append("the earlier video changed")
    partial_video = folder / "v.partial.mp4"
    if code == 130 and partial_video.exists() and "v.partial.mp4" not in err:
        problems.append("a partial video left without a word of it")
    leftovers = [n for n in _leftovers(folder, {"v.mp4", "v.partial.mp4"})]
    if leftovers:
        problems.append(f"files left: {leftovers}")
    return problems, max(peak, peak2), code


def _signal_an_infer(sig, fraction: float, work: Path):
    """``infer`` over an earlier bundle, signalled at a moment of its run (late moments fall while the
    bundle is written): the earlier bundle whole or the new one, and no partial folder beside it
    (``.bundle.partial.PID.hex`` stayed for ever)."""
    folder = work / "scenarios" / f"infer_{sig.name}_{fraction:.3f}"
    folder.mkdir(parents=True)
    out = folder / "bundle"
    args = ["infer", PHOTO, "--mask", MASK, "--size", "64", "--max-size", "256", "-o", out]
    code, _, err, seconds, peak = run_command(args)
    if code != 0:
        return [f"the first infer failed: {err[-200:]}"], peak, code
    proc = _start(args, folder)
    time.sleep(seconds * fraction)
    proc.send_signal(sig)
    code, err, peak2 = _reap(proc)
    return _interrupted(sig, code, err) + _bundle_left_whole(out, folder), max(peak, peak2), code


def _batch_names(stem: str, work: Path):
    """A photo whose stem is ``..``, ``.``, hidden or one of the batch's own names, in the folder the
    batch writes into, run twice: everything inside that folder, the second run finds it done."""
    folder = work / "scenarios" / f"batch_names_{stem.strip('.') or 'dots'}_{len(stem)}" / "shoot"
    folder.mkdir(parents=True)
    shutil.copy(PHOTO, folder / f"{stem}.jpg")
    env = {**os.environ, "RELIGHT_CACHE": str(folder.parent / "cache" / "lights")}
    args = ["batch", folder, "--env", asset_dir() / "envmaps" / "venice_sunset_256.hdr", "-o", folder, "--max-size", "256",
            "--workers", "1"]
    problems, peak, code = [], 0, None
    for run in range(2):
        code, out, err, _, p = run_command(args, env)
        peak = max(peak, p)
        if code != 0 or "Traceback" in err:
            problems.append(f"run {run + 1}: exit {code}: {err[-200:]!r}")
    outside = sorted(p.name for p in folder.parent.iterdir() if p.name not in ("shoot", "cache"))
    if outside:
        problems.append(f"written beside the batch's folder: {outside}")
    if code == 0 and "already done" not in out:
        problems.append(f"the second run did not find the item done: {out.strip().splitlines()[-1:]}")
    return problems, peak, code


def _streams(how: str, work: Path):
    """A render with a standard stream closed or full (``>&-``, ``2>&-``, ``>/dev/full``): the
    frame written, exit 0, no traceback."""
    folder = work / "scenarios" / f"streams_{how.replace(' ', '_')}"
    folder.mkdir(parents=True)

    closed = {"stdout closed": (1,), "stderr closed": (2,), "stdin closed": (0,), "every stream closed": (1, 2, 0)}
    setup = ChildSetup(full_stdout=how == "stdout a full device", close=closed.get(how, ()))
    code, _, err, _, peak = run_command(["render", SCENE, LIGHTS, "--size", "64", "-o", folder / "x.png"], setup=setup)
    problems = [] if code == 0 and "Traceback" not in err and (folder / "x.png").is_file() else [f"exit {code}: {err[-200:]!r}"]
    return problems, peak, code


def _surroundings(what: str, value: str, k: int, work: Path):
    """``MESA_GL_VERSION_OVERRIDE`` set (below 4.1: one line naming it; else the render runs), or a
    working folder deleted before the command starts (one line)."""
    folder = work / "scenarios" / f"surroundings_{what}_{value}_{k}"
    folder.mkdir(parents=True)
    args = ["render", SCENE, LIGHTS, "--size", "64", "-o", folder / "x.png"]
    if what == "gl":
        code, _, err, _, peak = run_command(args, {**os.environ, "MESA_GL_VERSION_OVERRIDE": value})
        low = float(value) < 4.1
        lines = err.strip().splitlines()
        if low:
            ok = code == 2 and len(lines) == 1 and "MESA_GL_VERSION_OVERRIDE" in lines[0]
        else:
            ok = code in (0, 2) and "Traceback" not in err and (code == 0 or len(lines) == 1)
        return ([] if ok else [f"exit {code}: {err[-200:]!r}"]), peak, code
    gone = folder / "gone"
    gone.mkdir()

    def leave():
        os.chdir(gone)
        os.rmdir(gone)

    # the installed ``relight`` script itself (an absolute path), forked here and waited for with its
    # peak (wait4): the campaign's ``python -c`` wrapper cannot start in a deleted folder (Python
    # computes its path from there), the program can
    import sys

    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # a relative entry there stops Python itself
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: into the folder, the folder deleted, then the program
        try:
            os.dup2(write_end, 2)
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 1)
            leave()
            os.execve(str(Path(sys.executable).with_name("relight")), ["relight", *map(str, args)], env)
        finally:
            os._exit(127)
    os.close(write_end)
    with os.fdopen(read_end, "rb") as stream:
        err = stream.read().decode("utf-8", "replace")
    _, status, usage = os.wait4(pid, 0)
    code, peak = os.waitstatus_to_exitcode(status), usage.ru_maxrss
    lines = err.strip().splitlines()
    ok = code == 2 and len(lines) == 1 and "working folder is gone" in lines[0]
    return ([] if ok else [f"exit {code}: {err[-200:]!r}"]), peak, code


FILE_SIZE_LIMIT = 100_000  # bytes a file may grow to where no small file system can be mounted (not root)


def _memory_limit(limit_mb: int, k: int, work: Path):
    """A render under an address-space limit (``ulimit -v``): done, or one line (numpy's MemoryError
    and OpenGL's refusals were tracebacks)."""
    folder = work / "scenarios" / f"ulimit_{limit_mb}_{k}"
    folder.mkdir(parents=True)
    code, _, err, _, peak = run_command(["render", SCENE, "--env", asset_dir() / "envmaps" / "venice_sunset_256.hdr", "--size", "128",
                                         "-o", folder / "x.png"], setup=ChildSetup(rlimits={"RLIMIT_AS": limit_mb << 20}))
    lines = [line for line in err.strip().splitlines() if not line.startswith(("  ", "fitting "))]
    ok = "Traceback" not in err and (code == 0 or (code == 2 and len(lines) == 1 and lines[0].startswith("relight: error:")))
    return ([] if ok else [f"exit {code}: {err[-300:]!r}"]), peak, code


def _full_disk(work: Path):
    """A 400 KB tmpfs (as root; otherwise a 100 KB file-size limit on the process, the same failed
    write): one line naming the file, the old frame's PNG and EXR kept, no temporary file."""
    folder = work / "scenarios" / "small_disk"
    folder.mkdir(parents=True)
    root = os.geteuid() == 0
    if root:
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(folder)], check=True)
    try:
        args = ["render", SCENE, LIGHTS, "-o", folder / "x.png"]
        code, _, err, _, peak = run_command([*args, "--size", "64"])
        if code != 0:
            return [f"the first render failed: {err[-200:]}"], peak, code
        if root:
            stat = os.statvfs(folder)
            (folder / "filler").write_bytes(os.urandom(max(stat.f_bavail * stat.f_frsize - 40_000, 0)))
        old = {p.name: p.read_bytes() for p in folder.iterdir()}
        setup = ChildSetup() if root else ChildSetup(rlimits={"RLIMIT_FSIZE": FILE_SIZE_LIMIT})
        code, _, err, _, peak2 = run_command([*args, "--size", "512", "--yaw", "90"], setup=setup)
        lines = err.strip().splitlines()
        problems = []
        if code != 2 or len(lines) != 1 or not lines[0].startswith(f"relight: error: {folder}/x."):
            problems.append(f"exit {code}, said {err[-300:]!r}")
        if {p.name: p.read_bytes() for p in folder.iterdir()} != old:
            problems.append(f"the old outputs changed or files were left: {_leftovers(folder, set(old))}")
        return problems, max(peak, peak2), code
    finally:
        if root:
            subprocess.run(["umount", str(folder)], check=True)


def _bundle_left_whole(out: Path, folder: Path) -> list[str]:
    """Problems of the bundle ``out`` left in ``folder``: it does not load, or something is beside it."""
    from viewer.errors import InputError
    from viewer.scene.bundle import load_scene

    problems = []
    try:
        load_scene(out)
    except InputError as exc:
        problems.append(f"the bundle left does not load: {exc}")
    if _leftovers(folder, {"bundle"}):
        problems.append(f"files left: {_leftovers(folder, {'bundle'})}")
    return problems


def _two_writers(k: int, work: Path):
    """Two ``infer`` into one ``-o`` at once: they take turns (both done) or one is refused; the
    bundle left is whole and loads."""
    folder = work / "scenarios" / f"race_{k}"
    folder.mkdir(parents=True)
    out = folder / "bundle"
    args = ["infer", PHOTO, "--mask", MASK, "--size", "64", "--max-size", "256", "-o", out]
    procs = [_start(args, folder) for _ in range(2)]
    results = [_reap(p) for p in procs]
    problems = [f"exit {code}: {err[-200:]!r}" for code, err, _ in results if code not in (0, 2) or "Traceback" in err]
    if not any(code == 0 for code, _, _ in results):
        problems.append("neither writer finished")
    problems += _bundle_left_whole(out, folder)
    return problems, max(peak for _, _, peak in results), max(code for code, _, _ in results)


def _read_only_map(work: Path):
    """A map in a folder nobody may write (a read-only bind mount as root, the mode bits otherwise):
    its lights go to the cache, the plot where asked (a traceback once), and the folder is untouched."""
    folder = work / "scenarios" / "read_only"
    (folder / "maps").mkdir(parents=True)
    shutil.copy(asset_dir() / "envmaps" / "venice_sunset_256.hdr", folder / "maps")
    root = os.geteuid() == 0
    seen = folder / "seen"
    seen.mkdir()
    if root:
        subprocess.run(["mount", "--bind", "-o", "ro", str(folder / "maps"), str(seen)], check=True)
    else:
        seen.rmdir()
        seen = folder / "maps"
        seen.chmod(0o555)
    try:
        code, _, err, _, peak = run_command(["fit-lights", seen / "venice_sunset_256.hdr", "-n", "4", "--method",
                                             "median-cut", "--plot", folder / "plot.png"],
                                            {**os.environ, "RELIGHT_CACHE": str(folder / "cache")})
        problems = [] if code == 0 and "Traceback" not in err and (folder / "plot.png").is_file() \
            else [f"exit {code}: {err[-300:]!r}"]
        if sorted(p.name for p in seen.iterdir()) != ["venice_sunset_256.hdr"]:
            problems.append("the read-only folder was written")
        return problems, peak, code
    finally:
        if root:
            subprocess.run(["umount", str(seen)], check=True)
        else:
            seen.chmod(0o755)
