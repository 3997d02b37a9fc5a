"""New LiDAR for an existing dataset: rescan its worlds with another sensor, or drop rings.

Both write a complete KITTI-format dataset at the output root, so every other command runs on
it unchanged: every file of the source except velodyne/, velodyne_info/ and meta/ is hard-
linked (copied where links are impossible), so images, labels, calib, planes, splits and the
depth/instance side data stay byte-identical; velodyne/ and velodyne_info/ are new; meta/ is
rewritten with the new sensor and per-actor LiDAR point counts. A frame is done once its meta
(or, without meta, its .bin) exists, so an interrupted run resumes. `lidar.json` at the root
records what was done; a second run into the same root must ask for the same thing.
"""

from __future__ import annotations

import json
import os
import shutil
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from kitti.io import atomic_write_text
from kitti.velodyne import read_velodyne, write_velodyne

from .io import INFO_DIR, info_path, read_scan_info, velodyne_path, write_scan, write_scan_info
from .rings import kept_rings, recover_rings, reduce_rings
from .scan import scan
from .spec import preset

PARTS = ("training", "testing")
NEW_DIRS = ("velodyne", INFO_DIR, "meta")
PROVENANCE = "lidar.json"
MANIFEST = "simgen.json"  # the generator's manifest: its "lidar" entry follows the new sensor


def lidar_seed(seed: int, frame_index: int) -> int:
    """The scan seed of a generated frame; `testbed generate` derives it the same way, so a
    rescan with the generating sensor reproduces the original scan bit for bit."""
    return zlib.crc32(f"lidar:{seed}:{frame_index}".encode())


def _link_or_copy(src: Path, dst: Path) -> None:
    if dst.exists():
        return
    dst.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(src, dst)
    except OSError:
        tmp = dst.with_name(f".{dst.name}.tmp")
        shutil.copy2(src, tmp)
        os.replace(tmp, dst)


def mirror_dataset(src: Path, dst: Path) -> None:
    """Link every source file into dst except the LiDAR and meta folders of each part."""
    if src.resolve() == dst.resolve():
        raise ValueError(f"--out {dst} is the source dataset itself; choose a new directory")
    for path in sorted(src.rglob("*")):
        rel = path.relative_to(src)
        if not path.is_file() or rel.name in (PROVENANCE, MANIFEST) \
                or any(part.startswith(".") for part in rel.parts):
            continue  # hidden files are stage markers (.done) or half-written temporaries
        if len(rel.parts) >= 3 and rel.parts[0] in PARTS and rel.parts[1] in NEW_DIRS:
            continue
        _link_or_copy(path, dst / rel)


def claim_output(src: Path, dst: Path, request: dict) -> None:
    """Write dst/lidar.json, or check that an earlier run there asked for the same thing.

    The source is recorded relative to dst, so the same request gives the same bytes wherever the
    two datasets live (a sweep on another backend or machine writes identical files)."""
    path = dst / PROVENANCE
    dst.mkdir(parents=True, exist_ok=True)
    record = {"source": os.path.relpath(src.resolve(), dst.resolve()), **request}
    if path.exists():
        old = json.loads(path.read_text())
        if old != record:
            diff = sorted(k for k in set(old) | set(record) if old.get(k) != record.get(k))
            raise ValueError(f"{path}: {dst} was made by a different request ({', '.join(diff)}); "
                             "use a new --out directory")
        return
    atomic_write_text(path, json.dumps(record, sort_keys=True, indent=1) + "\n")
    manifest = src / MANIFEST
    if manifest.exists():
        m = json.loads(manifest.read_text())
        if request["command"] == "rescan":
            m["lidar"] = request["lidar"]
        elif isinstance(m.get("lidar"), dict):
            m["lidar"] = {**m["lidar"], "beams": request["beams"]}
        atomic_write_text(dst / MANIFEST, json.dumps(m, sort_keys=True, indent=1) + "\n")


def _dump_meta(meta: dict) -> str:
    return json.dumps(meta, sort_keys=True, indent=1) + "\n"  # as simgen.meta.dumps


def _read_meta(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: line {e.lineno}: not valid JSON: {e.msg}") from None


def _update_meta(meta: dict, counts: dict[int, int], lidar: dict) -> dict:
    meta = dict(meta, lidar=lidar)
    meta["actors"] = [dict(a, lidar_points=int(counts.get(int(a["id"]), 0)))
                      for a in meta.get("actors", [])]
    return meta


@dataclass(frozen=True)
class RescanJob:
    src: Path  # source part folder (…/training)
    dst: Path
    fid: str
    lidar: dict  # preset, beams, max_range, and optionally weather (a LiDAR-only override)


def rescan_ids(src: Path, part: str = "training") -> list[str]:
    meta_dir = src / part / "meta"
    ids = sorted(p.stem for p in meta_dir.glob("*.json"))
    if not ids:
        raise ValueError(f"{meta_dir}: no meta/NNNNNN.json to rebuild worlds from "
                         "(rescan needs a dataset written by `testbed generate`)")
    return ids


def rescan_frame(job: RescanJob) -> str:
    """Rebuild one frame's world from its meta and scan it with the requested sensor."""
    from ..meta import world_from_meta  # the scene package; imported late to keep workers lean

    meta_out = job.dst / "meta" / f"{job.fid}.json"
    if meta_out.exists() and velodyne_path(job.dst, job.fid).exists() \
            and info_path(job.dst, job.fid).exists():
        return job.fid
    meta_path = job.src / "meta" / f"{job.fid}.json"
    meta = _read_meta(meta_path)
    try:
        world = world_from_meta(meta)
    except (KeyError, TypeError, ValueError) as e:
        raise ValueError(f"{meta_path}: cannot rebuild the world: {e}") from None
    if job.lidar.get("weather"):  # the sensor sees other weather; the images keep the world's
        world.weather = replace(world.weather, **job.lidar["weather"])
    spec = preset(job.lidar["preset"], beams=job.lidar.get("beams"),
                  max_range=job.lidar.get("max_range"))
    s = scan(world, spec, lidar_seed(int(meta["seed"]), int(meta["frame_index"])))
    write_scan(job.dst, job.fid, s)
    atomic_write_text(meta_out, _dump_meta(_update_meta(meta, s.point_counts(), job.lidar)))
    return job.fid


@dataclass(frozen=True)
class ReduceJob:
    src: Path  # source part folder
    dst: Path
    fid: str
    beams: int
    source_beams: int | None  # None: from the frame's meta, else 64 (KITTI's HDL-64E)


def reduce_ids(src: Path, part: str) -> list[str]:
    return sorted(p.stem for p in (src / part / "velodyne").glob("*.bin"))


def _source_beams(meta: dict | None, given: int | None) -> int:
    if given is not None:
        return given
    lidar = (meta or {}).get("lidar")
    if isinstance(lidar, dict) and lidar.get("preset"):
        return preset(lidar["preset"], beams=lidar.get("beams")).beams
    return 64


def check_reduction(job: ReduceJob) -> None:
    """Fail before any work when --beams cannot divide the (first frame's) source beams."""
    meta_in = job.src / "meta" / f"{job.fid}.json"
    meta = _read_meta(meta_in) if meta_in.exists() else None
    kept_rings(_source_beams(meta, job.source_beams), job.beams)


def reduce_frame(job: ReduceJob) -> str:
    """Keep every k-th ring of one scan; rings from the side file, else recovered."""
    meta_in = job.src / "meta" / f"{job.fid}.json"
    meta_out = job.dst / "meta" / f"{job.fid}.json"
    done = meta_out if meta_in.exists() else velodyne_path(job.dst, job.fid)
    if done.exists():
        return job.fid
    meta = _read_meta(meta_in) if meta_in.exists() else None
    n_in = _source_beams(meta, job.source_beams)
    pts = read_velodyne(velodyne_path(job.src, job.fid))
    ipath = info_path(job.src, job.fid)
    info = read_scan_info(ipath, len(pts)) if ipath.exists() else None
    ring = info["ring"] if info is not None else recover_rings(pts, n_in)[0]
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
        atomic_write_text(meta_out, _dump_meta(_update_meta(
            meta, {int(i): int(n) for i, n in zip(u, c)}, lidar)))
    return job.fid
