"""The scene generator: specs -> worlds -> camera renders, exact labels, KITTI datasets.

spec (YAML specs, factors) -> sample (worlds from a spec and a seed: road, scenery, meshes,
rigs) -> render (pyrender colour, depth, instance ids) + look (weather, sensor) -> labels
(derived from the geometry and the renders) -> generate (the KITTI writer, meta/ via meta).
The LiDAR lives in simgen.lidar and scans the same World.
"""

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy loads)
