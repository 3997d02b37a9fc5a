"""Rotating multi-beam LiDAR: real sensor presets, exact occlusion by one batched Embree
query, per-ray time with ego and actor motion, noise, intensity, weather, and beam reduction.

Frames: LiDAR x forward, y left, z up (KITTI velodyne). Rings: 0 = top beam. Times: seconds
from the camera trigger, when the head faces forward; a 10 Hz sweep spans [-0.05, 0.05] s.
"""

from .dataset import lidar_seed
from .io import read_scan, read_scan_info, write_scan
from .rays import RayTable, ray_table
from .rings import kept_rings, recover_rings, reduce_rings
from .scan import CLUTTER_ID, LidarScan, scan
from .spec import PRESETS, LidarSpec, preset
from .target import Target, build_target

__all__ = [
    "CLUTTER_ID", "PRESETS", "LidarScan", "LidarSpec", "RayTable", "Target", "build_target",
    "kept_rings", "lidar_seed", "preset", "ray_table", "read_scan", "read_scan_info",
    "recover_rings", "reduce_rings", "scan", "write_scan",
]
