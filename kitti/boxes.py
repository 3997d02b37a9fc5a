"""3D box geometry in the rectified camera frame.

A box is a row [x, y, z, h, w, l, ry]: (x, y, z) the bottom-face centre, h along -y (up), l along
the object's heading, w across it, ry the rotation about camera +y; ry = 0 faces camera +x and the
heading is (cos ry, 0, -sin ry).
"""

from __future__ import annotations

import warnings

import numpy as np

from .calib import Calibration

# Unit corners in the object frame (x along l, y down, z along w); 0-3 bottom face, 4-7 top.
UNIT_CORNERS = np.array([[0.5, 0, 0.5], [0.5, 0, -0.5], [-0.5, 0, -0.5], [-0.5, 0, 0.5],
                         [0.5, -1, 0.5], [0.5, -1, -0.5], [-0.5, -1, -0.5], [-0.5, -1, 0.5]])
# The 12 edges as corner index pairs.
EDGES = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                  [0, 4], [1, 5], [2, 6], [3, 7]])


def wrap_angle(a):
    """Wrap to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def rot_y(ry) -> np.ndarray:
    """(N, 3, 3) rotations about camera +y."""
    ry = np.atleast_1d(np.asarray(ry, dtype=float))
    c, s = np.cos(ry), np.sin(ry)
    r = np.zeros((len(ry), 3, 3))
    r[:, 0, 0], r[:, 0, 2], r[:, 1, 1], r[:, 2, 0], r[:, 2, 2] = c, s, 1.0, -s, c
    return r


def box_corners(boxes7: np.ndarray) -> np.ndarray:
    """(N, 8, 3) corners in the rectified camera frame."""
    b = np.asarray(boxes7, dtype=float).reshape(-1, 7)
    local = UNIT_CORNERS[None] * np.stack([b[:, 5], b[:, 3], b[:, 4]], axis=1)[:, None, :]
    return np.einsum("nij,nkj->nki", rot_y(b[:, 6]), local) + b[:, None, :3]


def lidar_upright_corners(boxes7: np.ndarray, calib: Calibration) -> np.ndarray:
    """(N, 8, 3) corners, in the rectified camera frame, of each box stood upright in the LiDAR's
    frame instead: the same bottom-face centre, size and heading, turned about the LiDAR's z.

    KITTI's objects were annotated as yaw-only boxes in the Velodyne point clouds, and its 2D
    boxes are their projections; label_2 keeps a yaw about camera y only, dropping the tilt
    between the two frames (about 0.6 deg of pitch and of roll in KITTI's calibration). So a
    label's 2D box is the projection of these corners, not of `box_corners`: on the real dev
    frames the sides of the vehicles' boxes lie a median 0.2 px from the one and 0.6 px from the
    other."""
    b = np.asarray(boxes7, dtype=float).reshape(-1, 7)
    bottom = calib.rect_to_lidar(b[:, :3])
    ahead = calib.rect_to_lidar(b[:, :3] + np.stack([np.cos(b[:, 6]), np.zeros(len(b)), -np.sin(b[:, 6])], 1))
    yaw = np.arctan2(ahead[:, 1] - bottom[:, 1], ahead[:, 0] - bottom[:, 0])
    c, s = np.cos(yaw), np.sin(yaw)
    # UNIT_CORNERS' object frame (x along l, y down, z along w) in the LiDAR's (x ahead, y left, z up).
    lx, ly, lz = (UNIT_CORNERS[None, :, i] * d[:, None] for i, d in enumerate((b[:, 5], b[:, 3], b[:, 4])))
    fwd, left, up = lx, lz, -ly
    pts = np.stack([c[:, None] * fwd - s[:, None] * left, s[:, None] * fwd + c[:, None] * left, up], -1)
    return calib.lidar_to_rect((pts + bottom[:, None, :]).reshape(-1, 3)).reshape(-1, 8, 3)


def alpha_from_rotation_y(ry, x, z):
    """Observation angle: alpha = ry - atan2(x, z), wrapped to [-pi, pi)."""
    return wrap_angle(np.asarray(ry) - np.arctan2(x, z))


def rotation_y_from_alpha(alpha, x, z):
    return wrap_angle(np.asarray(alpha) + np.arctan2(x, z))


def project_boxes(boxes7: np.ndarray, calib: Calibration, image_size: tuple[int, int],
                  cam: int = 2, near: float = 0.1, upright: str = "camera") -> np.ndarray:
    """(N, 4) image boxes [x1, y1, x2, y2] of projected 3D boxes, clipped to the image.

    upright "camera" projects the boxes as label_2 states them; "lidar" projects them stood upright
    in the LiDAR's frame, which is how KITTI's 2D label boxes were made (`lidar_upright_corners`).
    Edges that cross the near plane are cut there first, so a box partly behind the camera still
    gets the right extent. A box entirely behind the near plane gets NaNs.
    """
    if upright not in ("camera", "lidar"):
        raise ValueError(f"upright must be 'camera' or 'lidar', not {upright!r}")
    corners = box_corners(boxes7) if upright == "camera" else lidar_upright_corners(boxes7, calib)
    a, b = corners[:, EDGES[:, 0]], corners[:, EDGES[:, 1]]  # (N, 12, 3)
    za, zb = a[..., 2:3], b[..., 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (near - za) / (zb - za)
    cut = a + np.clip(t, 0, 1) * (b - a)
    crosses = ((za < near) != (zb < near))[..., 0]
    pts = np.concatenate([corners, cut], axis=1)  # (N, 20, 3)
    valid = np.concatenate([corners[..., 2] >= near, crosses], axis=1)
    uv, _ = calib.rect_to_image(pts.reshape(-1, 3), cam)
    uv = uv.reshape(len(corners), -1, 2)
    big = np.where(valid[..., None], uv, np.nan)
    with warnings.catch_warnings():  # all-NaN rows: boxes entirely behind the camera
        warnings.simplefilter("ignore", RuntimeWarning)
        lo, hi = np.nanmin(big, axis=1), np.nanmax(big, axis=1)
    w, h = image_size
    out = np.concatenate([lo, hi], axis=1)
    out[:, [0, 2]] = np.clip(out[:, [0, 2]], 0, w - 1)
    out[:, [1, 3]] = np.clip(out[:, [1, 3]], 0, h - 1)
    return out


def points_in_boxes(points_rect: np.ndarray, boxes7: np.ndarray) -> np.ndarray:
    """(N, M) mask: point m lies inside (or on) box n. Points in the rectified camera frame."""
    pts = np.asarray(points_rect, dtype=float).reshape(-1, 3)
    b = np.asarray(boxes7, dtype=float).reshape(-1, 7)
    d = pts[None, :, :] - b[:, None, :3]  # (N, M, 3)
    c, s = np.cos(b[:, 6])[:, None], np.sin(b[:, 6])[:, None]
    lx = c * d[..., 0] - s * d[..., 2]  # R^T d, R = rot_y(ry)
    lz = s * d[..., 0] + c * d[..., 2]
    ly = d[..., 1]
    return ((np.abs(lx) <= b[:, 5:6] / 2) & (np.abs(lz) <= b[:, 4:5] / 2)
            & (ly <= 0) & (ly >= -b[:, 3:4]))
