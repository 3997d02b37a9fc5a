"""One streaming pass over a dataset root: chunks of frame ids go to worker processes, each
returns only its accumulators, and a frame that cannot be read is skipped with its error (or,
asked, stops the pass naming its file: `UnreadableFrame`)."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2

from kitti.dataset import KittiDataset
from kitti.errors import KittiFormatError
from kitti.jobs import Backend, InProcess

from .images import car_look_stats, image_stats, read_image, road_surface_stats
from .labels import label_stats
from .lidar import lidar_stats
from .stats import Acc, DatasetStats, merge

MAX_CHUNK = 32
UNREADABLE = ("warn", "skip", "raise")  # what compute_stats does with a frame it cannot read


class UnreadableFrame(KittiFormatError):
    """A frame that cannot be read, when the pass is asked to stop there; the message names the
    frame, the root and the file."""


@dataclass(frozen=True)
class ChunkJob:
    """A few consecutive frame ids of one root, which optional groups it has, and whether a frame
    that cannot be read is skipped (recorded with its error) or stops the pass."""

    root: str
    ids: tuple[str, ...]
    lidar: bool
    labels: bool
    skip_unreadable: bool = True


def run_chunk(job: ChunkJob) -> Acc:
    """Worker: read every frame in full first, so a bad file leaves no partial values behind."""
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # one core per worker process: the pool fills the machine
    try:
        ds = KittiDataset(job.root)
        acc = Acc()
        for fid in job.ids:
            try:
                img = read_image(ds.image_path(fid))
                calib = ds.calib(fid) if job.lidar or job.labels else None
                scan = ds.velodyne(fid) if job.lidar else None
                labels = ds.labels(fid) if job.labels else None
                if job.lidar and scan is None:
                    raise KittiFormatError("no such file", ds.path("velodyne", fid, "bin"))
            except (KittiFormatError, OSError) as e:
                if not job.skip_unreadable:
                    raise UnreadableFrame(f"frame {fid} of {job.root} cannot be read: {e}") from None
                acc.skipped.append((fid, str(e)))
                continue
            acc.frames.append(fid)
            grey = image_stats(acc, img)
            if scan is not None:
                road = lidar_stats(acc, scan, calib, labels)
                if road is not None:
                    road_surface_stats(acc, img, grey, *road, calib)
            if labels is not None:
                label_stats(acc, labels, calib, (img.shape[1], img.shape[0]))
                car_look_stats(acc, grey, labels)
        return acc
    finally:
        cv2.setNumThreads(threads)


def compute_stats(root: str | Path, split: str | None = None, frames: int | None = None,
                  backend: Backend | None = None, unreadable: str = "warn") -> DatasetStats:
    """Statistics of the first `frames` ids of `split` (default: every frame with an image), with
    the chunks mapped on `backend` (default: in this process).

    A frame that cannot be read (`unreadable`): "warn", skipped with a warning; "skip", skipped
    silently (both listed in `DatasetStats.skipped`, with the error naming the file); "raise",
    the pass stops with `UnreadableFrame`."""
    if unreadable not in UNREADABLE:
        raise ValueError(f"unreadable must be one of {UNREADABLE}, got {unreadable!r}")
    ds = KittiDataset(root)
    ids = ds.ids(split)[:frames]
    groups = {"images": True, "lidar": (ds.dir / "velodyne").is_dir(),
              "labels": (ds.dir / "label_2").is_dir()}
    backend = backend or InProcess()
    workers = getattr(backend, "workers", None) or 2
    size = max(1, min(MAX_CHUNK, math.ceil(len(ids) / (4 * workers))))
    jobs = [ChunkJob(str(root), tuple(ids[i:i + size]), groups["lidar"], groups["labels"],
                     unreadable != "raise") for i in range(0, len(ids), size)]
    parts = backend.map(run_chunk, jobs, desc=f"fidelity {Path(root).name} ({len(ids)} frames)")
    stats = merge(str(root), split, groups, parts)
    for fid, err in stats.skipped if unreadable == "warn" else ():
        warnings.warn(f"fidelity: skipping frame {fid} of {root}: {err}", stacklevel=2)
    return stats
