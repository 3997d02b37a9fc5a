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

    def with_plane(self, plane: np.ndarray) -> "FramePoints":
        return FramePoints(self.rect, self.uv, rowdot(self.rect, plane[:3]) + plane[3], self.sensor)

    def in_box(self, bbox: np.ndarray) -> np.ndarray:
        """Indices of the returns whose pixel lies inside bbox [x1, y1, x2, y2]."""
        u, v = self.uv[:, 0], self.uv[:, 1]
        return np.flatnonzero((u >= bbox[0]) & (u <= bbox[2]) & (v >= bbox[1]) & (v <= bbox[3]))


MIN_DEPTH = 0.5
WEDGE_TAN = 1.2  # tan(50 deg)


def rowdot(pts: np.ndarray, v: np.ndarray) -> np.ndarray:
    """pts @ v without BLAS (see _affine)."""
    out = pts[:, 0] * v[0]
    for k in range(1, len(v)):
        out = out + pts[:, k] * v[k]
    return out


def _affine(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """m[:3, :3] @ p + m[:3, 3] for every row, column by column: a (N,3) @ (3,3) product through
    BLAS costs more in thread start-up than in arithmetic on a busy machine."""
    x, y, z = pts[:, 0], pts[:, 1], pts[:, 2]
    return np.stack([m[r, 0] * x + m[r, 1] * y + m[r, 2] * z + m[r, 3] for r in range(3)], axis=1)


def frame_points(velodyne: np.ndarray, calib: Calibration, plane: np.ndarray | None,
                 cam: int = 2) -> FramePoints:
    """The returns inside a 100-degree wedge around the camera's viewing direction (KITTI's colour
    camera sees about 80 degrees) and in front of the camera."""
    v = np.asarray(velodyne)
    axis = calib.velo_to_rect[2, :3]  # the camera's optical axis in the LiDAR frame
    ax, ay = axis[:2] / max(np.hypot(axis[0], axis[1]), 1e-9)
    along = v[:, 0] * ax + v[:, 1] * ay
    across = np.abs(v[:, 1] * ax - v[:, 0] * ay)
    v = v[(along > 0) & (across < WEDGE_TAN * along), :3].astype(np.float64)
    rect = _affine(calib.velo_to_rect, v)
    rect = rect[rect[:, 2] > MIN_DEPTH]
    P = calib.P(cam)
    hom = _affine(P, rect)
    uv = hom[:, :2] / hom[:, 2:3]
    height = rowdot(rect, plane[:3]) + plane[3] if plane is not None else np.full(len(rect), np.nan)
    sensor = calib.lidar_to_rect(np.zeros((1, 3)))[0]
    return FramePoints(rect, uv, height, sensor)
