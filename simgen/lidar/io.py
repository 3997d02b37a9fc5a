"""A simulated scan on disk: KITTI's velodyne/NNNNNN.bin plus the velodyne_info side file."""

from __future__ import annotations

from pathlib import Path

from kitti.velodyne import read_velodyne, write_velodyne
from kitti.velodyne_info import INFO_FIELDS, info_path, read_scan_info, velodyne_path, write_scan_info

from .scan import LidarScan


def write_scan(training_dir: str | Path, frame_id: str | int, scan: LidarScan) -> list[Path]:
    """velodyne/<id>.bin and velodyne_info/<id>.npz, each written atomically; their paths."""
    paths = [velodyne_path(training_dir, frame_id), info_path(training_dir, frame_id)]
    write_velodyne(paths[0], scan.points)
    write_scan_info(paths[1], {k: getattr(scan, k) for k in INFO_FIELDS})
    return paths


def read_scan(training_dir: str | Path, frame_id: str | int) -> LidarScan:
    pts = read_velodyne(velodyne_path(training_dir, frame_id))
    info = read_scan_info(info_path(training_dir, frame_id), len(pts))
    return LidarScan(points=pts, **info)
