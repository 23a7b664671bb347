"""Where a batch's tasks run: worker processes on this machine (:class:`LocalPool`), or Ray actors on
a cluster (:class:`RayPool`). Both take task dicts and give back result dicts, each handing a task
to an idle worker only; a worker that dies mid-task has its task run again (at most ``RETRIES``
times), so every item ends done or failed exactly once in the manifest."""

from __future__ import annotations

import multiprocessing
import os
import time
from collections import deque
from multiprocessing.connection import wait

from viewer.errors import InputError

RETRIES = 2


class LocalPool:
    """``workers`` processes, each one GL context and ``threads`` threads (spawned: no GL or torch
    state is inherited), each with its own pipe: a task is handed to an idle worker and the pool
    knows which task each worker holds, so a worker that dies (killed, out of memory) is replaced
    and its task run again, and no lock shared between processes can be left held."""

    def __init__(self, workers: int, threads: int):
        from viewer.batch.worker import serve

        self._mp = multiprocessing.get_context("spawn")
        self._serve, self.threads = serve, threads
        self._slots = [self._start() for _ in range(workers)]
        self._waiting: deque = deque()
        self._tries: dict[int, int] = {}
        self._idle_deaths = 0

    def _start(self) -> dict:
        ours, theirs = self._mp.Pipe()
        p = self._mp.Process(target=self._serve, args=(self.threads, theirs, os.getpid()), daemon=True)
        p.start()
        theirs.close()
        return {"proc": p, "conn": ours, "task": None}

    @property
    def size(self) -> int:
        return len(self._slots)

    def submit(self, task: dict) -> None:
        self._waiting.append(task)
        self._dispatch()

    def _dispatch(self):
        for slot in self._slots:
            if slot["task"] is None and self._waiting and slot["proc"].is_alive():
                task = self._waiting.popleft()
                slot["task"] = task
                try:
                    slot["conn"].send(task)
                except OSError:  # it died meanwhile: seen as dead below, its task given again
                    pass

    def results(self, timeout: float = 0.5) -> list[dict]:
        out = []
        watched = [slot["conn"] for slot in self._slots] + [slot["proc"].sentinel for slot in self._slots]
        ready = set(wait(watched, timeout))
        for i, slot in enumerate(self._slots):
            if slot["conn"] in ready:
                try:
                    out.append(slot["conn"].recv())
                    slot["task"] = None
                    continue
                except (EOFError, OSError):
                    pass  # its end of the pipe is gone: it died
            if slot["conn"] in ready or slot["proc"].sentinel in ready or not slot["proc"].is_alive():
                out += self._replace(i)
        self._dispatch()
        return out

    def _replace(self, i: int) -> list[dict]:
        """Worker ``i`` died: a new one in its place; its task again, or failed after RETRIES."""
        slot = self._slots[i]
        slot["proc"].join(1.0)
        code = slot["proc"].exitcode
        slot["conn"].close()
        self._slots[i] = self._start()
        task = slot["task"]
        if task is None:
            self._idle_deaths += 1
            if self._idle_deaths > 3 * len(self._slots):
                raise InputError(None, f"the batch's workers keep dying before any task (exit code {code}): "
                                       "see the lines above")
            return []
        tries = self._tries[task["id"]] = self._tries.get(task["id"], 0) + 1
        if tries <= RETRIES:
            self._waiting.appendleft(task)
            return []
        return [{"kind": "result", "id": task["id"], "ok": False,
                 "error": f"its worker died {tries} times (exit code {code}: killed, or out of memory?)"}]

    def close(self) -> None:
        for slot in self._slots:
            try:
                slot["conn"].send(None)
            except OSError:
                pass
        deadline = time.monotonic() + 5.0
        for slot in self._slots:
            slot["proc"].join(max(0.0, deadline - time.monotonic()))
            if slot["proc"].is_alive():
                slot["proc"].kill()
                slot["proc"].join(1.0)
            slot["conn"].close()


CONNECT_SECONDS = 5.0  # a cluster's head that does not answer within this is one line, not minutes of retries


def reachable(address: str) -> None:
    """One line when ``address`` (``HOST:PORT``, or ``auto``/``local`` left to Ray) names a head
    that does not take a connection within :data:`CONNECT_SECONDS` (Ray retried a dead address for
    minutes, deaf to SIGINT and SIGTERM)."""
    import socket

    if address in ("auto", "local") or ":" not in address:
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        with socket.create_connection((host or "127.0.0.1", int(port)), timeout=CONNECT_SECONDS):
            pass
    except (OSError, ValueError) as exc:
        raise InputError(None, f"--ray {address}: no Ray head answers there ({getattr(exc, 'strerror', None) or exc}); "
                               "start one (ray start --head) or give its address") from None


class RayPool:
    """One Ray actor per worker, each holding its GL context (EGL; a GPU where its node has one and
    the actor asks for it), restarted by Ray when its process dies and its task retried there."""

    def __init__(self, address: str, workers: int | None, threads: int, gpus: float = 0.0, start_timeout: float = 120.0):
        try:
            import ray
        except ImportError:
            raise InputError(None, "--ray needs Ray: pip install 'ray==2.60.0' (the project's cluster extra)") from None
        from viewer.batch.worker import Worker

        self._ray = ray
        if not ray.is_initialized():
            reachable(address)
            ray.init(address=address, include_dashboard=False, log_to_driver=False, logging_level="ERROR")
        cpus = int(ray.available_resources().get("CPU", 0))
        count = workers or max(1, cpus // threads)
        remote = ray.remote(num_cpus=threads, num_gpus=gpus, max_restarts=-1, max_task_retries=RETRIES)(Worker)
        actors = [remote.remote(threads) for _ in range(count)]
        # only actors the cluster could place and start get tasks (one it cannot place waits forever)
        pings = {a.pid.remote(): a for a in actors}
        started, _ = ray.wait(list(pings), num_returns=len(pings), timeout=start_timeout)
        self._actors = [pings[ref] for ref in started]
        for a in set(actors) - set(self._actors):
            ray.kill(a)
        if not self._actors:
            raise InputError(None, f"no Ray worker started within {start_timeout:.0f} s: the cluster has no free "
                                   f"{threads} CPU{'s' if threads > 1 else ''}{f' and {gpus:g} GPU' if gpus else ''} for one")
        self._idle = list(self._actors)
        self._waiting: list[dict] = []
        self._running: dict = {}  # object ref -> (actor, task)

    @property
    def size(self) -> int:
        return len(self._actors)

    def submit(self, task: dict) -> None:
        self._waiting.append(task)
        self._dispatch()

    def _dispatch(self):
        while self._idle and self._waiting:
            actor, task = self._idle.pop(), self._waiting.pop(0)
            self._running[actor.run.remote(task)] = (actor, task)

    def results(self, timeout: float = 0.5) -> list[dict]:
        out = []
        if self._running:  # back as soon as one is done (its actor gets the next task), with all done by then
            done, _ = self._ray.wait(list(self._running), num_returns=1, timeout=timeout)
            if done:
                done, _ = self._ray.wait(list(self._running), num_returns=len(self._running), timeout=0)
            for ref in done:
                actor, task = self._running.pop(ref)
                self._idle.append(actor)
                try:
                    result = self._ray.get(ref)
                except self._ray.exceptions.RayError as exc:  # retries spent: the item fails, the batch goes on
                    result = {"ok": False, "error": f"its Ray worker failed: {type(exc).__name__}"}
                out.append({**result, "kind": "result", "id": task["id"]})
        else:
            time.sleep(min(timeout, 0.05))
        self._dispatch()
        return out

    def close(self) -> None:
        for actor in self._actors:
            self._ray.kill(actor)
