"""The same worlds, another LiDAR: rebuild every frame's world from its meta and scan it again.

A rescan is a derived dataset (`kitti.derived`): images, labels, calib and planes are linked and
stay byte-identical, velodyne/ and velodyne_info/ are new, meta/ records the new sensor and each
actor's returns. A frame is done once its meta, .bin and side file exist, so a stopped rescan
resumes. The scan seed is the generator's (`lidar_seed`), so a rescan with the generating sensor
reproduces the original scans bit for bit.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from kitti.derived import claim_output, dump_json, meta_with_lidar, mirror_dataset
from kitti.io import WriteBehind, atomic_write_text
from kitti.jobs import Backend, InProcess
from kitti.velodyne_info import info_path, velodyne_path

from .spec import LidarSection


def lidar_seed(seed: int, frame_index: int) -> int:
    """The scan seed of a generated frame, shared by generation and rescans."""
    return zlib.crc32(f"lidar:{seed}:{frame_index}".encode())


@dataclass(frozen=True)
class WeatherOverride:
    """Weather the LiDAR sees instead of the world's own (a sensor study: the images keep the
    world's weather). None leaves that part of the world's weather as it is."""

    fog_extinction: float | None = None  # beta, 1/m
    rain_rate: float | None = None  # mm/h

    def record(self) -> dict:
        return {k: v for k, v in (("fog_extinction", self.fog_extinction),
                                  ("rain_rate", self.rain_rate)) if v is not None}


@dataclass(frozen=True)
class RescanRequest:
    """The sensor (a preset, optionally with fewer beams or a shorter range) and its weather."""

    lidar: LidarSection
    weather: WeatherOverride | None = None

    def record(self) -> dict:
        """As written to lidar.json and to every frame's meta (the beam count always a number)."""
        from .lidar import sensor_record

        rec = sensor_record(self.lidar.preset, self.lidar.beams, self.lidar.max_range)
        if self.weather is not None and self.weather.record():
            rec["weather"] = self.weather.record()
        return rec


@dataclass(frozen=True)
class RescanOutput:
    """Where one request's scans of a frame go."""

    dst: Path  # output part folder (…/training)
    request: RescanRequest


@dataclass(frozen=True)
class RescanJob:
    """One frame of a source dataset, scanned for every output: the world is rebuilt once."""

    src: Path  # source part folder (…/training)
    fid: str
    outputs: tuple[RescanOutput, ...]


_WRITE_BEHIND = WriteBehind()  # one per process: each worker releases what it wrote


def _complete(dst: Path, fid: str) -> bool:
    """A frame is done once its meta, .bin and side file exist (meta is written last)."""
    return ((dst / "meta" / f"{fid}.json").exists() and velodyne_path(dst, fid).exists()
            and info_path(dst, fid).exists())


def _as_seen(world, weather: WeatherOverride | None):
    """The world as the LiDAR sees it: the override's weather instead of the world's own (the
    images keep theirs); the world itself is left as it is, for the next sensor."""
    if weather is None or not weather.record():
        return world
    return replace(world, weather=replace(world.weather, **weather.record()))


def rescan_frame(job: RescanJob) -> str:
    """Rebuild one frame's world from its meta and scan it with every output's sensor not yet
    done there. The world and its Embree target are built once for all of them (a LiDAR-only
    weather override changes what the scan sees, not the target)."""
    from .lidar import preset, scan, write_scan  # the simulator; imported in the worker
    from .lidar.target import TargetCache
    from .meta import load_world

    todo = [o for o in job.outputs if not _complete(o.dst, job.fid)]
    if not todo:
        return job.fid
    meta, world = load_world(job.src / "meta" / f"{job.fid}.json")
    targets = TargetCache(world)
    seed = lidar_seed(int(meta["seed"]), int(meta["frame_index"]))
    for out in todo:
        lidar = out.request.lidar
        spec = preset(lidar.preset, beams=lidar.beams, max_range=lidar.max_range)
        s = scan(_as_seen(world, out.request.weather), spec, seed, target=targets.get(spec))
        scan_files = write_scan(out.dst, job.fid, s)
        meta_path = out.dst / "meta" / f"{job.fid}.json"
        atomic_write_text(meta_path, dump_json(meta_with_lidar(meta, s.point_counts(), out.request.record())))
        _WRITE_BEHIND.written([*scan_files, meta_path])
    return job.fid


def rescan_jobs(src: Path, outputs: Sequence[tuple[Path, RescanRequest]]) -> list[RescanJob]:
    """Check every request, claim and mirror each output root, and list one job per frame of
    `src` that serves all of them."""
    from .lidar import preset
    from .meta import meta_ids

    for _, request in outputs:
        lidar = request.lidar
        preset(lidar.preset, beams=lidar.beams, max_range=lidar.max_range)  # fail before any work
    ids = meta_ids(src, "rescan")
    for out, request in outputs:
        claim_output(src, out, {"command": "rescan", "lidar": request.record()})
        mirror_dataset(src, out)
    parts = tuple(RescanOutput(out / "training", request) for out, request in outputs)
    return [RescanJob(src / "training", fid, parts) for fid in ids]


def rescan(src: Path, out: Path, request: RescanRequest, backend: Backend | None = None) -> list[str]:
    """Write `out`: the worlds of `src` scanned by the requested sensor; the frame ids."""
    jobs = rescan_jobs(src, [(out, request)])
    return (backend or InProcess()).map(rescan_frame, jobs, desc=f"rescan {request.lidar.preset}")
