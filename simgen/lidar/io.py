"""A scan on disk: velodyne/NNNNNN.bin (KITTI) plus velodyne_info/NNNNNN.npz beside it.

The side file holds, per point of the .bin and in the same order, ring (uint8, 0 = top beam),
azimuth (float32 rad), time (float32 s from the camera trigger) and actor_id (int32, 0 =
background, -1 = weather clutter). It is a zip written with fixed timestamps, so the same scan
gives the same bytes (numpy's own savez stamps the current time).
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from kitti.errors import KittiFormatError
from kitti.io import atomic_write_bytes
from kitti.velodyne import read_velodyne, write_velodyne

from .scan import LidarScan

INFO_DIR = "velodyne_info"
INFO_FIELDS = {"ring": np.uint8, "azimuth": np.float32, "time": np.float32, "actor_id": np.int32}


def info_path(training_dir: str | Path, frame_id: str | int) -> Path:
    return Path(training_dir) / INFO_DIR / f"{_fid(frame_id)}.npz"


def velodyne_path(training_dir: str | Path, frame_id: str | int) -> Path:
    return Path(training_dir) / "velodyne" / f"{_fid(frame_id)}.bin"


def _fid(frame_id: str | int) -> str:
    return f"{int(frame_id):06d}" if isinstance(frame_id, (int, np.integer)) else str(frame_id)


def info_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, dtype in INFO_FIELDS.items():
            arr = io.BytesIO()
            np.lib.format.write_array(arr, np.ascontiguousarray(arrays[name], dtype=dtype),
                                      allow_pickle=False)
            zi = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            zi.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(zi, arr.getvalue())
    return buf.getvalue()


def write_scan_info(path: str | Path, arrays: dict[str, np.ndarray]) -> None:
    atomic_write_bytes(path, info_bytes(arrays))


def write_scan(training_dir: str | Path, frame_id: str | int, scan: LidarScan) -> None:
    """velodyne/<id>.bin and velodyne_info/<id>.npz, each written atomically."""
    write_velodyne(velodyne_path(training_dir, frame_id), scan.points)
    write_scan_info(info_path(training_dir, frame_id),
                    {k: getattr(scan, k) for k in INFO_FIELDS})


def read_scan_info(path: str | Path, n_points: int | None = None) -> dict[str, np.ndarray]:
    """The side file's arrays; checks names, lengths and (if given) the .bin's point count."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            out = {k: z[k] for k in INFO_FIELDS if k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        raise KittiFormatError(f"unreadable scan side file: {e}", path) from e
    for k in INFO_FIELDS:
        if k not in out:
            raise KittiFormatError("missing array in scan side file", path, None, k)
    lengths = {len(v) for v in out.values()}
    if len(lengths) != 1:
        raise KittiFormatError(f"arrays of different lengths {sorted(lengths)}", path)
    if n_points is not None and lengths != {n_points}:
        raise KittiFormatError(f"{lengths.pop()} entries but the .bin has {n_points} points",
                               path)
    return out


def read_scan(training_dir: str | Path, frame_id: str | int) -> LidarScan:
    pts = read_velodyne(velodyne_path(training_dir, frame_id))
    info = read_scan_info(info_path(training_dir, frame_id), len(pts))
    return LidarScan(points=pts, **info)
