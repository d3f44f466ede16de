"""The evaluation engine of ``printapp sweep`` and ``printapp solve``: designs evaluated on Dask, cached.

Each job is a resolved design (the text of its ``design.resolved.toml``) and a level
(:data:`printapp.evaluate.LEVELS`). Its result is cached in ``CACHE/<hash>.json``, the hash
taken over the resolved text, the level and the versions of printapp and the numerical
libraries, and written (atomically) the moment the job finishes: a sweep or a solve that
is stopped resumes where it was, and never recomputes a finished design.

Jobs run on a ``distributed`` cluster: by default a :class:`distributed.LocalCluster` of
worker processes on this machine (one thread each, numba single-threaded in each, so that
the workers, not threads, share the cores; each gets its share of the memory budget), or
the scheduler at ``scheduler`` (its workers need printapp installed and the design's files
at the same paths). ``workers = 0`` runs the jobs here, one after another, without Dask.
Results come back in job order whatever order they finish in, and are the same bytes for
any number of workers.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from types import TracebackType
from typing import Any

from printapp.evaluate import evaluate_resolved

_VERSIONED = ("printapp", "numpy", "numba", "scipy", "mitsuba", "pydantic")


@dataclass(frozen=True)
class Job:
    """One design to evaluate: its resolved text, how far, and where a ``design`` run writes."""

    resolved: str
    level: str
    out_dir: str | None = None

    @property
    def key(self) -> str:
        """The cache key: a hash of the resolved design, the level and the versions."""
        versions = {name: _version(name) for name in _VERSIONED}
        text = json.dumps([self.resolved, self.level, versions], sort_keys=True)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()[:32]


@dataclass
class Outcome:
    """A job's result, whether it came from the cache, and its wall time (s) where computed here."""

    result: dict[str, Any]
    cached: bool
    seconds: float = 0.0
    worker: str = ""


def _version(name: str) -> str:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "not installed"


@dataclass
class Engine:
    """Runs :class:`Job` lists on Dask (or here, with ``workers = 0``), through the cache.

    Use as a context manager; the cluster starts on the first jobs that miss the cache and
    closes on leaving the block (also on an interrupt).
    """

    cache_dir: Path | None
    workers: int = 2
    scheduler: str | None = None
    progress: Callable[[int, int, int], None] | None = None
    """Called with (done, total, from the cache) as jobs finish."""
    memory_budget: int | None = None
    """Bytes for all local workers together (default: printapp's budget); each gets its share."""
    hits: int = 0
    computed: int = 0
    _client: Any = field(default=None, repr=False)
    _cluster: Any = field(default=None, repr=False)

    def __enter__(self) -> Engine:
        if self.cache_dir is not None:
            from printapp.errors import PrintappError

            try:
                self.cache_dir.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise PrintappError(
                    f"{self.cache_dir}: cannot create the cache folder ({exc.strerror})"
                ) from None
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        client, cluster = self._client, self._cluster
        self._client = self._cluster = None
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()

    @property
    def where(self) -> str:
        """Where the jobs run, in words."""
        if self.scheduler is not None:
            return f"the Dask scheduler at {self.scheduler}"
        if self.workers == 0:
            return "this process (no Dask)"
        return f"a Dask LocalCluster of {self.workers} worker process{'es' if self.workers > 1 else ''}"

    def _start(self) -> Any:
        if self._client is not None:
            return self._client
        import logging

        from distributed import Client, LocalCluster

        if self.scheduler is not None:
            from printapp.errors import PrintappError

            try:
                self._client = Client(self.scheduler, timeout="10s")
            except (OSError, TimeoutError) as exc:
                raise PrintappError(
                    f"--scheduler: cannot reach a Dask scheduler at {self.scheduler} ({exc})"
                ) from None
            return self._client
        from printapp.memory import budget_bytes

        logging.getLogger("distributed").setLevel(logging.ERROR)  # no INFO lines on closing
        share = max(1, (self.memory_budget or budget_bytes()) // max(1, self.workers))
        env = {
            "NUMBA_NUM_THREADS": "1",
            "OMP_NUM_THREADS": "1",
            "PRINTAPP_MAX_MEMORY": str(share),
        }
        self._cluster = LocalCluster(
            n_workers=self.workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",  # its HTTP server on a free port (":8787" may be taken)
            silence_logs=logging.ERROR,
            env=env,
        )
        self._client = Client(self._cluster)
        return self._client

    def _load(self, key: str) -> dict[str, Any] | None:
        if self.cache_dir is None:
            return None
        path = self.cache_dir / f"{key}.json"
        try:
            entry = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        return entry.get("result") if entry.get("key") == key else None

    def _store(self, job: Job, key: str, result: dict[str, Any]) -> None:
        if self.cache_dir is None:
            return
        from printapp.outputs import atomic_write_bytes

        entry = {"key": key, "level": job.level, "result": result}
        atomic_write_bytes(
            self.cache_dir / f"{key}.json", (json.dumps(entry, sort_keys=True) + "\n").encode()
        )

    def run(self, jobs: list[Job]) -> list[Outcome]:
        """Every job's outcome, in job order; finished jobs are cached as they finish."""
        from printapp.interrupts import check as check_interrupt

        keys = [job.key for job in jobs]
        outcomes: list[Outcome | None] = [None] * len(jobs)
        todo: dict[str, list[int]] = {}
        for i, key in enumerate(keys):
            cached = self._load(key)
            if cached is not None:
                outcomes[i] = Outcome(cached, True)
            else:
                todo.setdefault(key, []).append(i)
        hits = len(jobs) - sum(len(v) for v in todo.values())
        self.hits += hits
        done = hits
        self._report(done, len(jobs), hits)

        def finish(key: str, result: dict[str, Any], seconds: float, worker: str) -> None:
            nonlocal done
            self._store(jobs[todo[key][0]], key, result)
            for i in todo[key]:
                outcomes[i] = Outcome(result, False, seconds, worker)
            done += len(todo[key])
            self.computed += 1
            self._report(done, len(jobs), hits)

        if self.workers == 0 and self.scheduler is None:
            for key, indices in todo.items():
                job = jobs[indices[0]]
                start = time.perf_counter()
                result = evaluate_resolved(job.resolved, job.level, job.out_dir)
                finish(key, result, time.perf_counter() - start, "local")
                check_interrupt()
        elif todo:
            from distributed import as_completed

            client = self._start()
            futures = {}
            for key, indices in todo.items():
                job = jobs[indices[0]]
                future = client.submit(
                    _timed,
                    job.resolved,
                    job.level,
                    job.out_dir,
                    key=f"printapp-{job.level}-{key}",
                    pure=False,
                )
                futures[future] = key
            for future in as_completed(list(futures)):
                result, seconds, worker = future.result()
                finish(futures[future], result, seconds, worker)
                check_interrupt()
        return [o for o in outcomes if o is not None]

    def _report(self, done: int, total: int, hits: int) -> None:
        if self.progress is not None:
            self.progress(done, total, hits)


def _timed(resolved: str, level: str, out_dir: str | None) -> tuple[dict[str, Any], float, str]:
    """A worker's job: the result, its wall time and the worker's process id."""
    start = time.perf_counter()
    result = evaluate_resolved(resolved, level, out_dir)
    return result, time.perf_counter() - start, f"pid {os.getpid()}"
