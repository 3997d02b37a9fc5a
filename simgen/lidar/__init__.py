"""Rotating multi-beam LiDAR: real sensor presets, exact occlusion by one batched Embree
query (and small ones for the rays that pass glass and leaves; façade windows where the camera's
textures show them), per-ray time with ego and actor motion, noise, the reflectance channel as
KITTI's HDL-64E reports it, and weather.

Frames: LiDAR x forward, y left, z up (KITTI velodyne). Rings: 0 = top beam. Times: seconds
from the camera trigger, when the head faces forward; a 10 Hz sweep spans [-0.05, 0.05] s.
What works on any KITTI dataset (the velodyne_info format, ring recovery, beam reduction) lives
in `kitti`; rescanning a generated dataset's worlds is `simgen.rescan`.
"""

from .io import read_scan, write_scan
from .rays import RayTable, ray_table
from .scan import CLUTTER_ID, LidarScan, scan
from .spec import PRESETS, LidarSpec, preset, sensor_record
from .target import Target, build_target

__all__ = [
    "CLUTTER_ID", "PRESETS", "LidarScan", "LidarSpec", "RayTable", "Target", "build_target",
    "preset", "ray_table", "read_scan", "scan", "sensor_record", "write_scan",
]
