"""How a dataset-wide stage runs its per-frame jobs: any object with `map(fn, jobs, desc)`.

Library functions that touch many frames (generate, rescan, reduce beams) take such a backend,
so one pool serves a whole run (`testbed.backends`: local processes or Ray) and nothing nests a
pool inside a job. Without one they run in this process.
"""

from __future__ import annotations

from typing import Any, Callable, Protocol, Sequence

from tqdm import tqdm


class Backend(Protocol):
    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any], desc: str = "jobs") -> list[Any]:
        """fn over jobs (fn top-level and jobs picklable), results in job order."""
        ...


class InProcess:
    """Every job in this process, in order, with a progress bar."""

    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any], desc: str = "jobs") -> list[Any]:
        return [fn(j) for j in tqdm(list(jobs), desc=desc, unit="job")]
