"""velodyne/NNNNNN.bin: float32 x, y, z, reflectance in the LiDAR frame, nothing else."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import KittiFormatError
from .io import atomic_write_bytes


def read_velodyne(path: str | Path) -> np.ndarray:
    path = Path(path)
    size = path.stat().st_size
    if size % 16:
        raise KittiFormatError(f"size {size} bytes is not a multiple of 16 (float32 x, y, z, r)",
                               path, None, "size")
    return np.fromfile(path, dtype="<f4").reshape(-1, 4)


def write_velodyne(path: str | Path, points: np.ndarray) -> None:
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 4:
        raise ValueError(f"{path}: velodyne points must be N x 4, got {pts.shape}")
    atomic_write_bytes(path, np.ascontiguousarray(pts, dtype="<f4").tobytes())
