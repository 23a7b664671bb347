"""Where a batch's tasks run: worker processes on this machine (:class:`LocalPool`), or Ray actors on
a cluster (:class:`RayPool`). Both take task dicts and give back result dicts (``kind`` "started"
when a local worker takes a task, "result" when it is done); a worker that dies mid-task has its task
run again elsewhere (at most ``RETRIES`` times), so every item ends done or failed exactly once in
the manifest."""

from __future__ import annotations

import multiprocessing
import os
import queue
import time

RETRIES = 2


class LocalPool:
    """``workers`` processes, each one GL context and ``threads`` threads (spawned: no GL or torch
    state is inherited)."""

    def __init__(self, workers: int, threads: int):
        from .worker import serve

        self._mp = multiprocessing.get_context("spawn")
        self._serve, self.threads = serve, threads
        self._tasks, self._results = self._mp.Queue(), self._mp.Queue()
        self._procs = [self._start() for _ in range(workers)]
        self._taken: dict[int, dict] = {}  # pid -> the task it took
        self._given: dict[int, dict] = {}  # task id -> task, until its result
        self._tries: dict[int, int] = {}

    def _start(self):
        p = self._mp.Process(target=self._serve, args=(self.threads, self._tasks, self._results, os.getpid()), daemon=True)
        p.start()
        return p

    @property
    def size(self) -> int:
        return len(self._procs)

    def submit(self, task: dict) -> None:
        self._given[task["id"]] = task
        self._tasks.put(task)

    def results(self, timeout: float = 0.5) -> list[dict]:
        out = []
        try:
            out.append(self._results.get(timeout=timeout))
            while True:
                out.append(self._results.get_nowait())
        except queue.Empty:
            pass
        for r in out:
            if r.get("kind") == "started":
                self._taken[r["pid"]] = self._given.get(r["id"])
            else:
                self._taken.pop(r.get("pid"), None)
                self._given.pop(r["id"], None)
        return out + self._replace_dead()

    def _replace_dead(self) -> list[dict]:
        """Workers that died (killed, crashed): a new one in each place, their tasks again or failed."""
        out = []
        for i, p in enumerate(self._procs):
            if p.is_alive():
                continue
            self._procs[i] = self._start()
            task = self._taken.pop(p.pid, None)
            if task is None:
                continue
            tries = self._tries[task["id"]] = self._tries.get(task["id"], 0) + 1
            if tries <= RETRIES:
                self._tasks.put(task)
            else:
                self._given.pop(task["id"], None)
                out.append({"kind": "result", "id": task["id"], "ok": False,
                            "error": f"its worker died {tries} times (exit code {p.exitcode})", "pid": p.pid})
        return out

    def close(self) -> None:
        for _ in self._procs:
            self._tasks.put(None)
        deadline = time.monotonic() + 5.0
        for p in self._procs:
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.terminate()
                p.join(1.0)


class RayPool:
    """One Ray actor per worker, each holding its GL context (EGL; a GPU where its node has one and
    the actor asks for it), restarted by Ray when its process dies and its task retried there."""

    def __init__(self, address: str, workers: int | None, threads: int, gpus: float = 0.0):
        import ray

        from .worker import Worker

        self._ray = ray
        if not ray.is_initialized():
            ray.init(address=None if address == "local" else address, include_dashboard=False,
                     log_to_driver=False, logging_level="ERROR")
        cpus = int(ray.cluster_resources().get("CPU", 1))
        count = workers or max(1, cpus // threads)
        remote = ray.remote(num_cpus=threads, num_gpus=gpus, max_restarts=-1, max_task_retries=RETRIES)(Worker)
        self._actors = [remote.remote(threads) for _ in range(count)]
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
        if self._running:
            done, _ = self._ray.wait(list(self._running), num_returns=len(self._running), timeout=timeout)
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
