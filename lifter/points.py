"""One frame's LiDAR returns in the frames the lifters need: rectified camera, image, road height."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kitti.calib import Calibration


@dataclass
class FramePoints:
    """Returns in front of the camera (rect z > MIN_DEPTH), with their pixel and road height."""

    rect: np.ndarray    # (N, 3) rectified camera frame
    uv: np.ndarray      # (N, 2) pixel in image_2
    height: np.ndarray  # (N,) above the road plane (NaN when no plane was given)
    sensor: np.ndarray  # (3,) LiDAR origin in the rect frame: the rays come from here

    def in_box(self, bbox: np.ndarray) -> np.ndarray:
        """Indices of the returns whose pixel lies inside bbox [x1, y1, x2, y2]."""
        u, v = self.uv[:, 0], self.uv[:, 1]
        return np.flatnonzero((u >= bbox[0]) & (u <= bbox[2]) & (v >= bbox[1]) & (v <= bbox[3]))


MIN_DEPTH = 0.5


def frame_points(velodyne: np.ndarray, calib: Calibration, plane: np.ndarray | None,
                 cam: int = 2) -> FramePoints:
    rect = calib.lidar_to_rect(np.asarray(velodyne)[:, :3].astype(float))
    rect = rect[rect[:, 2] > MIN_DEPTH]
    uv, _ = calib.rect_to_image(rect, cam)
    height = rect @ plane[:3] + plane[3] if plane is not None else np.full(len(rect), np.nan)
    sensor = calib.lidar_to_rect(np.zeros((1, 3)))[0]
    return FramePoints(rect, uv, height, sensor)
