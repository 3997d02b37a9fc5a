"""Execution backends: the same independent jobs on a local process pool or on Ray.

A job is a picklable top-level function and one argument; results come back in job order, so both
backends write identical files whatever order the jobs finish in. A run opens one backend and
every stage maps its per-frame jobs on it (`kitti.jobs.Backend`): one pool per run, none nested.
"""

from __future__ import annotations

import gc
import multiprocessing as mp
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

from tqdm import tqdm

from kitti.cpu import pins


def _render_threads(workers: int) -> str:
    """Each worker's share of the cores for Mesa's software rasteriser (read at GL start-up)."""
    return str(max(1, (os.cpu_count() or 1) // max(1, workers)))


# A frame builds tens of thousands of short-lived mesh and geometry objects; at Python's default
# first threshold (700 allocations) the cyclic collector took 108 ms of an 849 ms frame, at 20000
# 25 ms (scenes/urban.yaml, results/simgen.md). Workers hold no long-lived cycles to reclaim.
GC_THRESHOLD = (20000, 20, 20)


# numpy's BLAS (OpenBLAS) starts a thread per core in every process that loads it; a pool already
# puts a process on each core, and their BLAS threads then spin against each other: `testbed
# fidelity` on 80 urban frames with 2 workers took 5.8 s with them and 2.5 s with one each
# (results/fidelity/README.md). A process reads these when it loads its BLAS, before any
# initializer runs, so the parent sets them for the workers it is about to spawn.
BLAS_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


# What a progress bar counts, by the first word of its stage's `desc`: the per-frame stages
# (generate, rescan, relabel, reduce beams) map one job per frame; a sweep's lift-and-evaluate
# ("points") and bootstrap jobs are one per point, fidelity's are chunks of frames.
UNITS = {"points": "point", "bootstrap": "point", "fidelity": "chunk", "jobs": "job"}


def _unit(desc: str) -> str:
    return UNITS.get(desc.split(" ", 1)[0], "frame")


def _init_worker(threads: str) -> None:
    os.environ.setdefault("LP_NUM_THREADS", threads)
    gc.set_threshold(*GC_THRESHOLD)


def _collected(fn: Callable[[Any], Any], job: Any) -> Any:
    """`fn(job)` in a pool worker, then the job's cyclic garbage collected. A frame leaves a few
    hundred objects in reference cycles; at GC_THRESHOLD they outlived the young collections and
    waited for a full one, hundreds of frames away, so a worker's peak memory grew through a long
    run (613 MB at frame 20, 718 MB at frame 1,000 of `scenes/urban.yaml`). A full collection walks
    every object (227k after a frame: 200-300 ms), so the first one freezes what the imports and the
    first job made, and every later one walks only what came since (under 5 ms)."""
    try:
        return fn(job)
    finally:
        gc.collect()
        if not gc.get_freeze_count():
            gc.freeze()


@dataclass
class LocalBackend:
    """A pool of `workers` processes (spawned: no EGL or torch state crosses a fork), started at
    the first map and reused by every later one until `close`; 1 = in this process."""

    workers: int = 1
    _pool: ProcessPoolExecutor | None = field(default=None, init=False, repr=False)

    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any], desc: str = "jobs") -> list[Any]:
        jobs = list(jobs)
        if self.workers <= 1 or len(jobs) <= 1:
            with tqdm(jobs, desc=desc, unit=_unit(desc)) as bar:  # closed before an error is shown
                return [fn(j) for j in bar]
        if self._pool is None:
            for var in BLAS_THREAD_VARS:  # inherited by the spawned workers
                os.environ.setdefault(var, "1")
            self._pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                             initializer=_init_worker,
                                             initargs=(_render_threads(self.workers),))
        results: list[Any] = [None] * len(jobs)
        futures = {self._pool.submit(_collected, fn, j): i for i, j in enumerate(jobs)}
        with tqdm(total=len(jobs), desc=desc, unit=_unit(desc)) as bar:
            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                bar.update(1)
        return results

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None

    def __enter__(self) -> LocalBackend:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass
class RayBackend:
    """Ray tasks on the cluster at `address`, or on a local Ray instance when address is None."""

    address: str | None = None
    workers: int | None = None

    def __post_init__(self) -> None:
        try:
            import ray
        except ImportError as e:  # ray is the optional extra `.[ray]`
            raise RuntimeError("the Ray backend needs `pip install -e .[ray]`") from e
        self._started = not ray.is_initialized()
        if self._started:
            # Ray's workers load numpy before they unpickle a job: the kernel pins (kitti.cpu) must
            # be in their environment from the start, on this host and on a cluster's.
            kwargs: dict[str, Any] = dict(include_dashboard=False, log_to_driver=False,
                                          configure_logging=False,
                                          runtime_env={"env_vars": pins()})
            if self.address:
                ray.init(address=self.address, **kwargs)
            else:  # the local workers inherit this process's environment
                os.environ.setdefault("LP_NUM_THREADS", _render_threads(self.workers or 1))
                ray.init(num_cpus=self.workers, _node_ip_address="127.0.0.1", **kwargs)
        self._ray = ray

    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any], desc: str = "jobs") -> list[Any]:
        ray = self._ray
        remote = ray.remote(fn)
        refs = [remote.remote(j) for j in jobs]
        index = {ref: i for i, ref in enumerate(refs)}
        results: list[Any] = [None] * len(refs)
        pending = list(refs)
        with tqdm(total=len(refs), desc=desc, unit=_unit(desc)) as bar:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    results[index[ref]] = ray.get(ref)
                    bar.update(1)
        return results

    def close(self) -> None:
        """Shut down the Ray instance this backend started (a cluster it joined lives on)."""
        if self._started:
            self._ray.shutdown()

    def __enter__(self) -> RayBackend:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


Backend = LocalBackend | RayBackend


def make_backend(name: str = "local", workers: int = 1, address: str | None = None) -> Backend:
    if name == "local":
        return LocalBackend(workers)
    if name == "ray":
        return RayBackend(address, workers)
    raise ValueError(f"unknown backend '{name}' (local or ray)")
