"""Write a KITTI-layout dataset from a scene spec: one independent job per frame.

Per frame, under <out>/training/: image_2 (PNG), label_2, calib, planes (the road plane in rect
camera coordinates: exact on a flat road, else fitted to the road 0-40 m ahead,
`simgen.road.RoadLayout.fitted_plane`), velodyne (+ the LiDAR's side file) when a LiDAR is set, and side data
KITTI tools ignore: depth_2 (16-bit PNG, camera-2 z in metres x 256, 0 = no surface or beyond
255.99 m, KITTI's depth-benchmark encoding), instance_2 (16-bit PNG, actor id, 0 = background)
and meta/NNNNNN.json (simgen.meta). Every file is written atomically and meta last, so a frame
counts as done exactly when its meta exists with every other file: an interrupted run resumes
where it stopped and never leaves a half-written frame.
"""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from kitti.calib import write_calib
from kitti.derived import MANIFEST, dump_json
from kitti.io import WriteBehind, atomic_write_bytes, atomic_write_text
from kitti.jobs import Backend, InProcess
from kitti.labels import write_label
from kitti.planes import write_plane
from kitti.splits import write_split

from . import meta as meta_io
from .factors import factor_rng
from .labels import derive
from .look import apply_look
from .render import render
from .rescan import lidar_seed
from .road import RoadLayout
from .sample import sample_world
from .shadows import WorldScene
from .spec import SceneSpec, spec_to_dict

DEPTH_SCALE = 256.0


@dataclass(frozen=True)
class Job:
    spec: SceneSpec
    seed: int
    index: int
    root: Path


def frame_id(index: int) -> str:
    return f"{index:06d}"


def frame_files(training: Path, fid: str, with_lidar: bool) -> list[Path]:
    files = [training / "image_2" / f"{fid}.png", training / "label_2" / f"{fid}.txt",
             training / "calib" / f"{fid}.txt", training / "planes" / f"{fid}.txt",
             training / "depth_2" / f"{fid}.png", training / "instance_2" / f"{fid}.png"]
    if with_lidar:
        files.append(training / "velodyne" / f"{fid}.bin")
    return files


# PNG row filter and zlib strategy per image kind (benchmarks/bench_png.py): one fixed filter
# instead of libpng's per-row search, the same pixels in a half to a third of the time. The camera
# image: Paeth (the best predictor of a photograph's pixel from its three neighbours), then
# run-length coding (sensor noise leaves LZ77 few long matches to find). The depth and instance
# maps are smooth or flat: the row above, then deflate (depth) or runs (ids). `testbed fidelity`
# measures the pixels' compressibility with an encoder of its own, not the files' sizes.
PNG_CAMERA = (cv2.IMWRITE_PNG_FILTER_PAETH, cv2.IMWRITE_PNG_STRATEGY_RLE)
PNG_DEPTH = (cv2.IMWRITE_PNG_FILTER_UP, cv2.IMWRITE_PNG_STRATEGY_DEFAULT)
PNG_INSTANCE = (cv2.IMWRITE_PNG_FILTER_UP, cv2.IMWRITE_PNG_STRATEGY_RLE)


def encode_png(img: np.ndarray, setting: tuple[int, int]) -> bytes:
    """PNG bytes of `img` with the given row filter(s) and zlib strategy (level 3)."""
    row_filter, strategy = setting
    ok, buf = cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, 3, cv2.IMWRITE_PNG_FILTER,
                                         row_filter, cv2.IMWRITE_PNG_STRATEGY, strategy])
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def encode_depth(depth: np.ndarray) -> np.ndarray:
    d = np.round(depth.astype(np.float64) * DEPTH_SCALE)
    return np.where((d > 0) & (d <= 65535), d, 0).astype(np.uint16)


def decode_depth(png16: np.ndarray) -> np.ndarray:
    return png16.astype(np.float32) / DEPTH_SCALE


def _lidar_api():
    """simgen.lidar, imported only when a frame has a LiDAR."""
    try:
        from . import lidar
    except ImportError as e:
        raise RuntimeError(f"the LiDAR simulation (simgen.lidar) cannot be imported: {e}") from None
    return lidar


_WRITE_BEHIND = WriteBehind()  # one per process: each worker releases what it wrote


def make_frame(job: Job) -> str:
    """Sample, render, label and write one frame; skip it if it is already complete."""
    fid = frame_id(job.index)
    training = job.root / "training"
    meta_path = training / "meta" / f"{fid}.json"
    section = job.spec.lidar
    if meta_path.exists() and all(p.exists() for p in frame_files(training, fid, section is not None)):
        return fid
    world = sample_world(job.spec, job.seed, job.index)
    target = None
    if section is not None:  # the LiDAR's scene of the world, built first: the sun's shadows use it too
        lidar = _lidar_api()
        lspec = lidar.preset(section.preset, beams=section.beams, max_range=section.max_range)
        target = lidar.build_target(world, lspec)
    out = render(world, None if target is None else WorldScene(target.scene, target.first_actor))
    rig = world.rig
    look_rng = factor_rng(job.seed, job.index, "look")
    image = apply_look(out.color, out.depth, rig.intrinsics(), world.weather, world.light,
                       world.sensor, look_rng, out.headroom, world.camera)
    counts = None
    lidar_info = None
    scan_files = []
    if section is not None:
        scan = lidar.scan(world, lspec, lidar_seed(job.seed, job.index), target)
        scan_files = lidar.write_scan(training, fid, scan)
        counts = scan.point_counts()
        lidar_info = lidar.sensor_record(section.preset, section.beams, section.max_range)
    objects, truths = derive(world, out.instance, job.spec.labels, counts)
    atomic_write_bytes(training / "image_2" / f"{fid}.png", encode_png(image[..., ::-1], PNG_CAMERA))
    atomic_write_bytes(training / "depth_2" / f"{fid}.png", encode_png(encode_depth(out.depth), PNG_DEPTH))
    atomic_write_bytes(training / "instance_2" / f"{fid}.png", encode_png(out.instance, PNG_INSTANCE))
    write_calib(training / "calib" / f"{fid}.txt", rig.calib)
    road = RoadLayout(**world.scenery["road"])
    write_plane(training / "planes" / f"{fid}.txt", rig.road_plane_rect(road.fitted_plane()))
    write_label(training / "label_2" / f"{fid}.txt", objects)
    meta = meta_io.world_to_meta(world, spec_to_dict(job.spec), truths, counts, lidar_info)
    atomic_write_text(meta_path, dump_json(meta))
    _WRITE_BEHIND.written(frame_files(training, fid, False) + scan_files + [meta_path])
    return fid


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
        atomic_write_text(path, dump_json(manifest))


def generate(spec: SceneSpec, out: str | Path, frames: int | None = None, seed: int | None = None,
             backend: Backend | None = None) -> list[str]:
    """Write (or finish writing) the dataset, one job per frame on `backend`; returns the ids."""
    root = Path(out)
    n = spec.frames if frames is None else frames
    seed = spec.seed if seed is None else seed
    if spec.lidar is None and spec.labels.min_lidar_points:
        raise ValueError("labels.min_lidar_points counts LiDAR returns: the spec needs a lidar")
    lidar = None if spec.lidar is None else \
        _lidar_api().sensor_record(spec.lidar.preset, spec.lidar.beams, spec.lidar.max_range)
    _check_manifest(root, {"spec": spec_to_dict(spec), "seed": seed, "lidar": lidar})
    jobs = [Job(spec, seed, i, root) for i in range(n)]
    (backend or InProcess()).map(make_frame, jobs, desc=f"generate {spec.name}")
    train, val = split_ids(n, spec.split.train_fraction, seed)
    sets = root / "ImageSets"
    write_split(sets / "train.txt", train)
    write_split(sets / "val.txt", val)
    write_split(sets / "trainval.txt", sorted(train + val))
    return [frame_id(i) for i in range(n)]
