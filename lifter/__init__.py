"""The lifter: 2D boxes plus LiDAR (or the image alone) to 3D boxes."""

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)
