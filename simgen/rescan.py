"""The same worlds, another LiDAR: rebuild every frame's world from its meta and scan it again.

A rescan is a derived dataset (`kitti.derived`): images, labels, calib and planes are linked and
stay byte-identical, velodyne/ and velodyne_info/ are new, meta/ records the new sensor and each
actor's returns. A frame is done once its meta, .bin and side file exist, so a stopped rescan
resumes. The scan seed is the generator's (`lidar_seed`), so a rescan with the generating sensor
reproduces the original scans bit for bit.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, replace
from pathlib import Path

from kitti.derived import claim_output, dump_json, meta_with_lidar, mirror_dataset
from kitti.io import atomic_write_text
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
class RescanJob:
    src: Path  # source part folder (…/training)
    dst: Path
    fid: str
    request: RescanRequest


def rescan_frame(job: RescanJob) -> str:
    """Rebuild one frame's world from its meta and scan it with the requested sensor."""
    from .lidar import preset, scan, write_scan  # the simulator; imported in the worker
    from .meta import load_world

    meta_out = job.dst / "meta" / f"{job.fid}.json"
    if meta_out.exists() and velodyne_path(job.dst, job.fid).exists() \
            and info_path(job.dst, job.fid).exists():
        return job.fid
    meta, world = load_world(job.src / "meta" / f"{job.fid}.json")
    lidar, weather = job.request.lidar, job.request.weather
    if weather is not None and weather.record():  # the sensor sees other weather, not the images
        world.weather = replace(world.weather, **weather.record())
    spec = preset(lidar.preset, beams=lidar.beams, max_range=lidar.max_range)
    s = scan(world, spec, lidar_seed(int(meta["seed"]), int(meta["frame_index"])))
    write_scan(job.dst, job.fid, s)
    atomic_write_text(meta_out, dump_json(meta_with_lidar(meta, s.point_counts(),
                                                          job.request.record())))
    return job.fid


def rescan_jobs(src: Path, out: Path, request: RescanRequest) -> list[RescanJob]:
    """Check the request, claim and mirror the output root, and list one job per frame."""
    from .lidar import preset
    from .meta import meta_ids

    lidar = request.lidar
    preset(lidar.preset, beams=lidar.beams, max_range=lidar.max_range)  # fail before any work
    ids = meta_ids(src, "rescan")
    claim_output(src, out, {"command": "rescan", "lidar": request.record()})
    mirror_dataset(src, out)
    return [RescanJob(src / "training", out / "training", fid, request) for fid in ids]


def rescan(src: Path, out: Path, request: RescanRequest, backend: Backend | None = None) -> list[str]:
    """Write `out`: the worlds of `src` scanned by the requested sensor; the frame ids."""
    jobs = rescan_jobs(src, out, request)
    return (backend or InProcess()).map(rescan_frame, jobs, desc=f"rescan {request.lidar.preset}")
