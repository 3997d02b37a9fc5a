"""velodyne_info/NNNNNN.npz: per-point ring, azimuth, time and actor id beside a KITTI scan.

KITTI's .bin holds x, y, z, reflectance only; the side file holds, per point of the .bin and in
the same order, ring (uint8, 0 = top beam), azimuth (float32 rad), time (float32 s from the camera
trigger) and actor_id (int32, 0 = background, -1 = weather clutter). It is a zip written with
fixed timestamps, so the same arrays give the same bytes (numpy's own savez stamps the current
time). Tools that know only KITTI ignore the folder; beam reduction reads its rings.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from .errors import KittiFormatError
from .io import atomic_write_bytes

INFO_DIR = "velodyne_info"
INFO_FIELDS = {"ring": np.uint8, "azimuth": np.float32, "time": np.float32, "actor_id": np.int32}


def info_path(part_dir: str | Path, frame_id: str | int) -> Path:
    return Path(part_dir) / INFO_DIR / f"{_fid(frame_id)}.npz"


def velodyne_path(part_dir: str | Path, frame_id: str | int) -> Path:
    return Path(part_dir) / "velodyne" / f"{_fid(frame_id)}.bin"


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
