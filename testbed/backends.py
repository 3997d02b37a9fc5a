"""Execution backends: the same independent jobs on a local process pool or on Ray.

A job is a picklable top-level function and one argument; results come back in job order, so both
backends write identical files whatever order the jobs finish in.
"""

from __future__ import annotations

import multiprocessing as mp
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from tqdm import tqdm


@dataclass
class LocalBackend:
    """A pool of `workers` processes (spawned: no EGL or torch state crosses a fork); 1 = in-process."""

    workers: int = 1

    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any], desc: str = "jobs") -> list[Any]:
        jobs = list(jobs)
        if self.workers <= 1 or len(jobs) <= 1:
            return [fn(j) for j in tqdm(jobs, desc=desc, unit="job")]
        results: list[Any] = [None] * len(jobs)
        with ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn")) as pool:
            futures = {pool.submit(fn, j): i for i, j in enumerate(jobs)}
            for fut in tqdm(as_completed(futures), total=len(jobs), desc=desc, unit="job"):
                results[futures[fut]] = fut.result()
        return results


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
        if not ray.is_initialized():
            kwargs: dict[str, Any] = dict(include_dashboard=False, log_to_driver=False,
                                          configure_logging=False)
            if self.address:
                ray.init(address=self.address, **kwargs)
            else:
                ray.init(num_cpus=self.workers, _node_ip_address="127.0.0.1", **kwargs)
        self._ray = ray

    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any], desc: str = "jobs") -> list[Any]:
        ray = self._ray
        remote = ray.remote(fn)
        refs = [remote.remote(j) for j in jobs]
        index = {ref: i for i, ref in enumerate(refs)}
        results: list[Any] = [None] * len(refs)
        pending = list(refs)
        with tqdm(total=len(refs), desc=desc, unit="job") as bar:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    results[index[ref]] = ray.get(ref)
                    bar.update(1)
        return results


Backend = LocalBackend | RayBackend


def make_backend(name: str = "local", workers: int = 1, address: str | None = None) -> Backend:
    if name == "local":
        return LocalBackend(workers)
    if name == "ray":
        return RayBackend(address, workers)
    raise ValueError(f"unknown backend '{name}' (local or ray)")
