"""Fewer LiDAR rings for any KITTI-format dataset: keep every k-th ring of each scan (thesis 000).

Rings come from the velodyne_info side file where there is one, else they are recovered from the
KITTI point order (`kitti.rings`), so this works on real KITTI as on generated data and needs no
simulator. The output root is a derived dataset (`kitti.derived`): everything else linked, scans
new, a generated dataset's meta/ following the new ring count. A frame is done once its meta (or,
without meta, its .bin) exists, so an interrupted run resumes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
import numpy as np

from .derived import PARTS, claim_output, dump_json, meta_with_lidar, mirror_dataset, read_json
from .io import atomic_write_text
from .jobs import Backend, InProcess
from .rings import kept_rings, recover_rings, reduce_rings
from .velodyne import read_velodyne, write_velodyne
from .velodyne_info import info_path, read_scan_info, velodyne_path, write_scan_info

KITTI_BEAMS = 64  # the HDL-64E of every real KITTI scan


@dataclass(frozen=True)
class ReduceJob:
    src: Path  # source part folder (…/training)
    dst: Path
    fid: str
    beams: int
    source_beams: int


def reduce_ids(src: Path, part: str) -> list[str]:
    return sorted(p.stem for p in (src / part / "velodyne").glob("*.bin"))


def source_beams_of(src: Path) -> int:
    """Beams of the dataset's scans: the count its meta's sensor record states when it was
    generated, else KITTI's 64."""
    for part in PARTS:
        first = next(iter(sorted((src / part / "meta").glob("*.json"))), None)
        lidar = read_json(first).get("lidar") if first else None
        if isinstance(lidar, dict) and lidar.get("preset"):
            beams = lidar.get("beams")
            if not isinstance(beams, int) or isinstance(beams, bool) or beams < 1:
                raise ValueError(f"{first}: field 'lidar.beams' is {beams!r}, not the scans' beam "
                                 "count; give it (--source-beams)")
            return beams
    return KITTI_BEAMS


def reduce_frame(job: ReduceJob) -> str:
    """Keep every k-th ring of one scan; rings from the side file, else recovered."""
    meta_in = job.src / "meta" / f"{job.fid}.json"
    meta_out = job.dst / "meta" / f"{job.fid}.json"
    done = meta_out if meta_in.exists() else velodyne_path(job.dst, job.fid)
    if done.exists():
        return job.fid
    meta = read_json(meta_in) if meta_in.exists() else None
    n_in = job.source_beams
    pts = read_velodyne(velodyne_path(job.src, job.fid))
    ipath = info_path(job.src, job.fid)
    info = read_scan_info(ipath, len(pts)) if ipath.exists() else None
    ring = info["ring"] if info is not None else recover_rings(pts, n_in).ring
    if len(ring) and int(ring.max()) >= n_in:
        raise ValueError(f"{ipath}: ring {int(ring.max())} but the sensor has {n_in} beams")
    mask, new_ring = reduce_rings(ring, n_in, job.beams)
    if info is not None:
        kept = {k: v[mask] for k, v in info.items()}
        kept["ring"] = new_ring
        write_scan_info(info_path(job.dst, job.fid), kept)
    write_velodyne(velodyne_path(job.dst, job.fid), pts[mask])
    if meta is not None:
        lidar = dict(meta.get("lidar") or {}, beams=job.beams)
        ids = kept["actor_id"] if info is not None else np.zeros(0, np.int32)
        u, c = np.unique(ids[ids > 0], return_counts=True)
        atomic_write_text(meta_out, dump_json(meta_with_lidar(
            meta, {int(i): int(n) for i, n in zip(u, c)}, lidar)))
    return job.fid


def reduce_jobs(src: Path, out: Path, beams: int, source_beams: int | None = None
                ) -> list[ReduceJob]:
    """Check the request, claim and mirror the output root, and list one job per scan.

    `source_beams` None: from the dataset (`source_beams_of`); it is recorded as given."""
    n_in = source_beams if source_beams is not None else source_beams_of(src)
    jobs = [ReduceJob(src / part, out / part, fid, beams, n_in)
            for part in PARTS for fid in reduce_ids(src, part)]
    if not jobs:
        raise ValueError(f"{src}: no training/velodyne/*.bin (or testing/) to reduce")
    kept_rings(n_in, beams)  # fail before any work when beams cannot divide the source's
    claim_output(src, out, {"command": "reduce-beams", "beams": beams,
                            "source_beams": source_beams})
    mirror_dataset(src, out)
    return jobs


def reduce_beams(src: Path, out: Path, beams: int, source_beams: int | None = None,
                 backend: Backend | None = None) -> list[str]:
    """Write `out`: `src` with every (source_beams / beams)-th ring of each scan; the frame ids."""
    jobs = reduce_jobs(src, out, beams, source_beams)
    return (backend or InProcess()).map(reduce_frame, jobs, desc=f"reduce to {beams} beams")
