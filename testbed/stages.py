"""Pipeline stages as library calls, each resumable: generate, rescan, reduce beams, detect, lift
and evaluate.

Each stage calls the library function a user would call from Python (and the `testbed`
subcommand wraps), writes into its own folder and marks it complete with a `.done` file written
last, so a stopped pipeline resumes by skipping what is marked. Stages that touch many frames map
their per-frame jobs on the run's one backend; the scan stages take many scans at once: every
frame of a dataset is one rescan job for all its scan configurations, and every frame of every
beam reduction is one job.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from kitti.io import atomic_write_text
from kitti.jobs import Backend

if TYPE_CHECKING:  # simgen is imported only when a stage that needs it runs
    from simgen.rescan import RescanRequest


def is_done(folder: Path) -> bool:
    return (folder / ".done").exists()


def mark_done(folder: Path, info: dict) -> None:
    atomic_write_text(folder / ".done", json.dumps(info, sort_keys=True, indent=1) + "\n")


def digest(*parts: object) -> str:
    """Short stable key of a stage's inputs (file contents for paths)."""
    h = hashlib.sha256()
    for p in parts:
        if isinstance(p, Path) and p.is_file():
            h.update(p.read_bytes())
        else:
            h.update(repr(p).encode())
    return h.hexdigest()[:10]


def generate(spec: Path, out: Path, frames: int | None, seed: int | None,
             backend: Backend) -> Path:
    from simgen.generate import generate as write_dataset
    from simgen.spec import load_spec

    if not is_done(out):
        write_dataset(load_spec(spec), out, frames=frames, seed=seed, backend=backend)
        mark_done(out, {"spec": str(spec), "frames": frames, "seed": seed})
    return out


def detect(data: Path, out: Path, split: str, threads: int = 2) -> Path:
    """The shipped detector over the split, in this process on `threads` CPU threads."""
    import torch

    from detector.infer import detect_dataset

    if not is_done(out):
        torch.set_num_threads(threads)
        detect_dataset(data, out, None, split)
        mark_done(out, {"data": str(data), "split": split})
    return out


@dataclass(frozen=True)
class Rescan:
    """One scan configuration of a generated dataset's worlds."""

    base: Path
    out: Path
    request: RescanRequest


def _batch(items: list, jobs_of: Callable, job: Callable, desc: str, done_info: Callable,
           backend: Backend) -> None:
    """The per-frame jobs of every item not yet done, as one batch on the backend; then each
    item is marked done with its record."""
    todo = [x for x in items if not is_done(x.out)]
    jobs = [j for x in todo for j in jobs_of(x)]
    if jobs:
        backend.map(job, jobs, desc=desc)
    for x in todo:
        mark_done(x.out, done_info(x))


def _rescan_record(s: Rescan) -> dict:
    lidar, weather = s.request.lidar, s.request.weather
    return {"data": str(s.base), "lidar": lidar.preset, "beams": lidar.beams,
            "max_range": lidar.max_range, "weather": None if weather is None else weather.record()}


def rescan(scans: list[Rescan], backend: Backend) -> None:
    """Every frame of every scan not yet done, as one batch of jobs on the backend: one job per
    frame of each base dataset, which rebuilds that frame's world and its Embree scene once and
    scans it for all of that base's configurations."""
    from simgen.rescan import rescan_frame, rescan_jobs

    todo = [s for s in scans if not is_done(s.out)]
    by_base: dict[Path, list[Rescan]] = {}
    for s in todo:
        by_base.setdefault(s.base, []).append(s)
    jobs = [j for base, group in by_base.items()
            for j in rescan_jobs(base, [(s.out, s.request) for s in group])]
    if jobs:
        backend.map(rescan_frame, jobs, desc="rescan")
    for s in todo:
        mark_done(s.out, _rescan_record(s))


@dataclass(frozen=True)
class Reduction:
    """Rings dropped from a dataset's scans: every (source / beams)-th one kept."""

    data: Path
    out: Path
    beams: int


def reduce_beams(reductions: list[Reduction], backend: Backend) -> None:
    from kitti.reduce import reduce_frame, reduce_jobs

    _batch(reductions,
           lambda r: reduce_jobs(r.data, r.out, r.beams),
           reduce_frame, "reduce beams", lambda r: {"data": str(r.data), "beams": r.beams}, backend)


@dataclass(frozen=True)
class LiftJob:
    """Lift a split's 2D boxes with one method and evaluate the result against the labels."""

    data: Path
    detections: Path | None  # None: the labels' boxes (oracle)
    method: str
    split: str
    out: Path
    range_bins: tuple[float, ...]


def lift_and_evaluate(job: LiftJob) -> dict:
    """Lift, evaluate, write out/eval.json; returns the evaluation JSON."""
    from kitti.eval import evaluate_folders
    from lifter.pipeline import lift_dataset

    result = job.out / "eval.json"
    if not is_done(job.out):
        lift_dataset(job.data, job.detections, job.method, job.out / "pred", job.split)
        res = evaluate_folders(job.data / "training" / "label_2", job.out / "pred",
                               job.data / "ImageSets" / f"{job.split}.txt",
                               range_bins=list(job.range_bins))
        atomic_write_text(result, json.dumps(res.to_json(), indent=1) + "\n")
        boxes = "gt" if job.detections is None else str(job.detections)
        mark_done(job.out, {"data": str(job.data), "boxes": boxes, "method": job.method})
    return json.loads(result.read_text())
