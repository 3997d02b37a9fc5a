"""One frame's LiDAR returns in the frames the lifters need: rectified camera, image, road height."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from kitti.calib import Calibration


@dataclass
class FramePoints:
    """Returns in front of the camera (rect z > MIN_DEPTH), with their pixel and road height."""

    rect: np.ndarray    # (N, 3) rectified camera frame
    uv: np.ndarray      # (N, 2) pixel in image_2
    height: np.ndarray  # (N,) above the road plane (NaN when no plane was given)
    sensor: np.ndarray  # (3,) LiDAR origin in the rect frame: the rays come from here

    def with_plane(self, plane: np.ndarray) -> FramePoints:
        return FramePoints(self.rect, self.uv, rowdot(self.rect, plane[:3]) + plane[3], self.sensor)

    def in_box(self, bbox: np.ndarray) -> np.ndarray:
        """Indices of the returns whose pixel lies inside bbox [x1, y1, x2, y2]."""
        u, v = self.uv[:, 0], self.uv[:, 1]
        return np.flatnonzero((u >= bbox[0]) & (u <= bbox[2]) & (v >= bbox[1]) & (v <= bbox[3]))


MIN_DEPTH = 0.5
WEDGE_TAN = 1.2  # tan(50 deg)


def rowdot(pts: np.ndarray, v: np.ndarray) -> np.ndarray:
    """pts @ v column by column: a (N,3) @ (3,) product through BLAS costs more in thread
    start-up than in arithmetic on a busy machine."""
    out = pts[:, 0] * v[0]
    for k in range(1, len(v)):
        out = out + pts[:, k] * v[k]
    return out


def frame_points(velodyne: np.ndarray, calib: Calibration, plane: np.ndarray | None,
                 cam: int = 2) -> FramePoints:
    """The returns inside a 100-degree wedge around the camera's viewing direction (KITTI's colour
    camera sees about 80 degrees) and in front of the camera."""
    v = np.asarray(velodyne)  # (N, >=3), any float type: read in place
    axis = calib.velo_to_rect[2, :3]  # the camera's optical axis in the LiDAR frame
    ax, ay = axis[:2] / max(np.hypot(axis[0], axis[1]), 1e-9)
    rect, uv = _to_camera(v, np.ascontiguousarray(calib.velo_to_rect[:3], dtype=np.float64),
                          np.ascontiguousarray(calib.P(cam), dtype=np.float64), ax, ay,
                          WEDGE_TAN, MIN_DEPTH)
    height = rowdot(rect, plane[:3]) + plane[3] if plane is not None else np.full(len(rect), np.nan)
    sensor = calib.lidar_to_rect(np.zeros((1, 3)))[0]
    return FramePoints(rect, uv, height, sensor)


@numba.njit(cache=True, nogil=True)
def _to_camera(v, m, P, ax, ay, wedge_tan, min_depth):
    """One pass over the scan: the wedge test, the rectified camera frame and the pixel of every
    return kept (numpy's version makes a dozen full-size temporaries of a 120k-return scan)."""
    n = v.shape[0]
    rect = np.empty((n, 3))
    uv = np.empty((n, 2))
    k = 0
    for i in range(n):
        x, y, z = v[i, 0], v[i, 1], v[i, 2]
        along = x * ax + y * ay
        if along <= 0.0 or abs(y * ax - x * ay) >= wedge_tan * along:
            continue
        rz = m[2, 0] * x + m[2, 1] * y + m[2, 2] * z + m[2, 3]
        if rz <= min_depth:
            continue
        rx = m[0, 0] * x + m[0, 1] * y + m[0, 2] * z + m[0, 3]
        ry = m[1, 0] * x + m[1, 1] * y + m[1, 2] * z + m[1, 3]
        w = P[2, 0] * rx + P[2, 1] * ry + P[2, 2] * rz + P[2, 3]
        uv[k, 0] = (P[0, 0] * rx + P[0, 1] * ry + P[0, 2] * rz + P[0, 3]) / w
        uv[k, 1] = (P[1, 0] * rx + P[1, 1] * ry + P[1, 2] * rz + P[1, 3]) / w
        rect[k, 0], rect[k, 1], rect[k, 2] = rx, ry, rz
        k += 1
    return rect[:k].copy(), uv[:k].copy()
