"""Write a KITTI-layout dataset from a scene spec: one independent job per frame.

Per frame, under <out>/training/: image_2 (PNG), label_2, calib, planes (the exact road plane in
rect camera coordinates), velodyne (+ the LiDAR's side file) when a LiDAR is set, and side data
KITTI tools ignore: depth_2 (16-bit PNG, camera-2 z in metres x 256, 0 = no surface or beyond
255.99 m, KITTI's depth-benchmark encoding), instance_2 (16-bit PNG, actor id, 0 = background)
and meta/NNNNNN.json (simgen.meta). Every file is written atomically and meta last, so a frame
counts as done exactly when its meta exists with every other file: an interrupted run resumes
where it stopped and never leaves a half-written frame.
"""

from __future__ import annotations

import json
import os
import zlib
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from kitti.calib import write_calib
from kitti.io import atomic_write_bytes, atomic_write_text
from kitti.labels import write_label
from kitti.planes import write_plane
from kitti.splits import write_split

from . import meta as meta_io
from .factors import factor_rng
from .labels import derive
from .look import apply_look
from .render import render
from .sample import sample_world
from .spec import LidarSection, SceneSpec, spec_to_dict

DEPTH_SCALE = 256.0
MANIFEST = "simgen.json"


@dataclass(frozen=True)
class Job:
    spec: SceneSpec
    seed: int
    index: int
    root: Path
    lidar: LidarSection | None


def frame_id(index: int) -> str:
    return f"{index:06d}"


def frame_files(training: Path, fid: str, with_lidar: bool) -> list[Path]:
    files = [training / "image_2" / f"{fid}.png", training / "label_2" / f"{fid}.txt",
             training / "calib" / f"{fid}.txt", training / "planes" / f"{fid}.txt",
             training / "depth_2" / f"{fid}.png", training / "instance_2" / f"{fid}.png"]
    if with_lidar:
        files.append(training / "velodyne" / f"{fid}.bin")
    return files


def _png(img: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, 3])
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def encode_depth(depth: np.ndarray) -> np.ndarray:
    d = np.round(depth.astype(np.float64) * DEPTH_SCALE)
    return np.where((d > 0) & (d <= 65535), d, 0).astype(np.uint16)


def decode_depth(png16: np.ndarray) -> np.ndarray:
    return png16.astype(np.float32) / DEPTH_SCALE


def _lidar_api():
    """simgen.lidar, and the scan seed its `testbed rescan` uses too (a rescan with the same
    sensor then reproduces the frame's scan bit for bit)."""
    try:
        from . import lidar
        from .lidar.dataset import lidar_seed
    except ImportError as e:
        raise RuntimeError(f"the LiDAR simulation (simgen.lidar) cannot be imported: {e}") from None
    return lidar, lidar_seed


def make_frame(job: Job) -> str:
    """Sample, render, label and write one frame; skip it if it is already complete."""
    fid = frame_id(job.index)
    training = job.root / "training"
    meta_path = training / "meta" / f"{fid}.json"
    if meta_path.exists() and all(p.exists() for p in frame_files(training, fid, job.lidar is not None)):
        return fid
    world = sample_world(job.spec, job.seed, job.index)
    out = render(world)
    rig = world.rig
    look_rng = factor_rng(job.seed, job.index, "look")
    image = apply_look(out.color, out.depth, rig.intrinsics(), world.weather, world.light,
                       world.sensor, look_rng)
    objects, truths = derive(world, out.instance, job.spec.labels)
    counts = None
    lidar_info = None
    if job.lidar is not None:
        lidar, lidar_seed = _lidar_api()
        lspec = lidar.preset(job.lidar.preset, beams=job.lidar.beams, max_range=job.lidar.max_range)
        scan = lidar.scan(world, lspec, lidar_seed(job.seed, job.index))
        lidar.write_scan(training, fid, scan)
        counts = scan.point_counts()
        lidar_info = job.lidar.model_dump()
    atomic_write_bytes(training / "image_2" / f"{fid}.png", _png(image[..., ::-1]))
    atomic_write_bytes(training / "depth_2" / f"{fid}.png", _png(encode_depth(out.depth)))
    atomic_write_bytes(training / "instance_2" / f"{fid}.png", _png(out.instance))
    write_calib(training / "calib" / f"{fid}.txt", rig.calib)
    write_plane(training / "planes" / f"{fid}.txt", rig.road_plane_rect())
    write_label(training / "label_2" / f"{fid}.txt", objects)
    meta = meta_io.world_to_meta(world, spec_to_dict(job.spec), truths, counts, lidar_info)
    atomic_write_text(meta_path, meta_io.dumps(meta))
    return fid


def _init_worker(threads: int) -> None:
    """Give each worker's software rasteriser its share of the cores (read at GL start-up)."""
    os.environ.setdefault("LP_NUM_THREADS", str(threads))


def split_ids(n: int, train_fraction: float, seed: int) -> tuple[list[str], list[str]]:
    """A deterministic shuffle of the frames into train and val."""
    order = np.random.default_rng([int(seed), zlib.crc32(b"split")]).permutation(n)
    k = int(round(train_fraction * n))
    k = min(max(k, 1), n - 1) if n > 1 else n
    return sorted(frame_id(i) for i in order[:k]), sorted(frame_id(i) for i in order[k:])


def _check_manifest(root: Path, manifest: dict) -> None:
    path = root / MANIFEST
    if path.exists():
        old = json.loads(path.read_text())
        if old != manifest:
            diff = sorted(k for k in manifest if old.get(k) != manifest.get(k))
            raise ValueError(f"{path}: {root} holds a dataset made with a different {', '.join(diff)};"
                             " use a new --out directory")
    else:
        atomic_write_text(path, json.dumps(manifest, sort_keys=True, indent=1) + "\n")


def generate(spec: SceneSpec, out: str | Path, frames: int | None = None, seed: int | None = None,
             workers: int = 2, lidar: LidarSection | None = None, progress: bool = True) -> list[str]:
    """Write (or finish writing) the dataset; returns the frame ids. lidar overrides spec.lidar."""
    root = Path(out)
    n = spec.frames if frames is None else frames
    seed = spec.seed if seed is None else seed
    lidar = lidar if lidar is not None else spec.lidar
    if lidar is not None:
        _lidar_api()  # fail before any work if the LiDAR code is missing
    _check_manifest(root, {"spec": spec_to_dict(spec), "seed": seed,
                           "lidar": None if lidar is None else lidar.model_dump()})
    jobs = [Job(spec, seed, i, root, lidar) for i in range(n)]
    bar = tqdm(total=n, desc=f"generate {spec.name}", unit="frame", disable=not progress)
    if workers <= 1:
        for j in jobs:
            make_frame(j)
            bar.update()
    else:
        threads = max(1, (os.cpu_count() or 1) // workers)
        with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn"),
                                 initializer=_init_worker, initargs=(threads,)) as pool:
            for _ in pool.map(make_frame, jobs):
                bar.update()
    bar.close()
    train, val = split_ids(n, spec.split.train_fraction, seed)
    sets = root / "ImageSets"
    write_split(sets / "train.txt", train)
    write_split(sets / "val.txt", val)
    write_split(sets / "trainval.txt", sorted(train + val))
    return [frame_id(i) for i in range(n)]
