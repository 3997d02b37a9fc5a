"""KITTI calibration and the four frames it links: LiDAR, reference camera 0, rectified camera 0,
and the image of camera 0..3.

    X_ref  = Tr_velo_to_cam · [X_lidar, 1]
    X_rect = R0_rect · X_ref
    x_img  ~ P_cam · [X_rect, 1]

Nothing is assumed identity; inverses are taken of the full 4x4 matrices, so a calibration whose
rotation is not exactly orthonormal (real KITTI files) still round-trips.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import KittiFormatError
from .io import atomic_write_text

KEYS = ("P0", "P1", "P2", "P3", "R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo")
_SHAPES = {"P0": (3, 4), "P1": (3, 4), "P2": (3, 4), "P3": (3, 4), "R0_rect": (3, 3),
           "Tr_velo_to_cam": (3, 4), "Tr_imu_to_velo": (3, 4)}


def _hom4(m: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[: m.shape[0], : m.shape[1]] = m
    return out


def _apply(m4: np.ndarray, pts: np.ndarray) -> np.ndarray:
    pts = np.asarray(pts, dtype=float).reshape(-1, 3)
    return pts @ m4[:3, :3].T + m4[:3, 3]


@dataclass
class Calibration:
    P0: np.ndarray
    P1: np.ndarray
    P2: np.ndarray
    P3: np.ndarray
    R0_rect: np.ndarray
    Tr_velo_to_cam: np.ndarray
    Tr_imu_to_velo: np.ndarray

    def __post_init__(self) -> None:
        for key in KEYS:
            setattr(self, key, np.asarray(getattr(self, key), dtype=float).reshape(_SHAPES[key]))

    # -- 4x4 transforms ------------------------------------------------------------------------
    @property
    def velo_to_ref(self) -> np.ndarray:
        return _hom4(self.Tr_velo_to_cam)

    @property
    def ref_to_rect4(self) -> np.ndarray:
        return _hom4(self.R0_rect)

    @property
    def velo_to_rect(self) -> np.ndarray:
        """4x4 rectified-camera-from-LiDAR."""
        return self.ref_to_rect4 @ self.velo_to_ref

    def P(self, cam: int = 2) -> np.ndarray:
        return getattr(self, f"P{cam}")

    # -- point maps (N,3) -> (N,3) -------------------------------------------------------------
    def lidar_to_ref(self, pts: np.ndarray) -> np.ndarray:
        return _apply(self.velo_to_ref, pts)

    def ref_to_lidar(self, pts: np.ndarray) -> np.ndarray:
        return _apply(np.linalg.inv(self.velo_to_ref), pts)

    def ref_to_rect(self, pts: np.ndarray) -> np.ndarray:
        return _apply(self.ref_to_rect4, pts)

    def rect_to_ref(self, pts: np.ndarray) -> np.ndarray:
        return _apply(np.linalg.inv(self.ref_to_rect4), pts)

    def lidar_to_rect(self, pts: np.ndarray) -> np.ndarray:
        return _apply(self.velo_to_rect, pts)

    def rect_to_lidar(self, pts: np.ndarray) -> np.ndarray:
        return _apply(np.linalg.inv(self.velo_to_rect), pts)

    # -- image ---------------------------------------------------------------------------------
    def rect_to_image(self, pts_rect: np.ndarray, cam: int = 2) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (N,2) and depth (N,) = rectified z of each point."""
        pts = np.asarray(pts_rect, dtype=float).reshape(-1, 3)
        hom = pts @ self.P(cam)[:, :3].T + self.P(cam)[:, 3]
        return hom[:, :2] / hom[:, 2:3], pts[:, 2].copy()

    def lidar_to_image(self, pts_lidar: np.ndarray, cam: int = 2) -> tuple[np.ndarray, np.ndarray]:
        return self.rect_to_image(self.lidar_to_rect(pts_lidar), cam)

    def image_to_rect(self, uv: np.ndarray, depth: np.ndarray, cam: int = 2) -> np.ndarray:
        """Invert rect_to_image: the rectified point with rect z = depth seen at pixel uv.

        Solves the two linear equations u·(P[2]·X) = P[0]·X and v·(P[2]·X) = P[1]·X for x, y,
        so a P with skew or a non-zero third-row translation (P2, P3) is handled exactly.
        """
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        z = np.asarray(depth, dtype=float).reshape(-1)
        P = self.P(cam)
        u, v = uv[:, 0], uv[:, 1]
        # rows: (P0 - u P2)·[x y z 1] = 0, (P1 - v P2)·[x y z 1] = 0
        a = P[0][None, :] - u[:, None] * P[2][None, :]
        b = P[1][None, :] - v[:, None] * P[2][None, :]
        ra = -(a[:, 2] * z + a[:, 3])
        rb = -(b[:, 2] * z + b[:, 3])
        det = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        x = (ra * b[:, 1] - a[:, 1] * rb) / det
        y = (a[:, 0] * rb - ra * b[:, 0]) / det
        return np.stack([x, y, z], axis=1)

    def intrinsics(self, cam: int = 2) -> np.ndarray:
        return self.P(cam)[:, :3].copy()

    @classmethod
    def kitti_default(cls) -> "Calibration":
        """The calibration of KITTI's 2011_09_26 drives (object frames such as 000000-era)."""
        return cls(
            P0=[[7.215377e02, 0, 6.095593e02, 0], [0, 7.215377e02, 1.728540e02, 0], [0, 0, 1, 0]],
            P1=[[7.215377e02, 0, 6.095593e02, -3.875744e02], [0, 7.215377e02, 1.728540e02, 0],
                [0, 0, 1, 0]],
            P2=[[7.215377e02, 0, 6.095593e02, 4.485728e01], [0, 7.215377e02, 1.728540e02, 2.163791e-01],
                [0, 0, 1, 2.745884e-03]],
            P3=[[7.215377e02, 0, 6.095593e02, -3.395242e02], [0, 7.215377e02, 1.728540e02, 2.199936e00],
                [0, 0, 1, 2.729905e-03]],
            R0_rect=[[9.999239e-01, 9.837760e-03, -7.445048e-03],
                     [-9.869795e-03, 9.999421e-01, -4.278459e-03],
                     [7.402527e-03, 4.351614e-03, 9.999631e-01]],
            Tr_velo_to_cam=[[7.533745e-03, -9.999714e-01, -6.166020e-04, -4.069766e-03],
                            [1.480249e-02, 7.280733e-04, -9.998902e-01, -7.631618e-02],
                            [9.998621e-01, 7.523790e-03, 1.480755e-02, -2.717806e-01]],
            Tr_imu_to_velo=[[9.999976e-01, 7.553071e-04, -2.035826e-03, -8.086759e-01],
                            [-7.854027e-04, 9.998898e-01, -1.482298e-02, 3.195559e-01],
                            [2.024406e-03, 1.482454e-02, 9.998881e-01, -7.997231e-01]],
        )


def _fmt(v: float) -> str:
    return np.format_float_scientific(float(v), unique=True, exp_digits=2)


def format_calib(calib: Calibration) -> str:
    return "".join(f"{k}: " + " ".join(_fmt(v) for v in getattr(calib, k).ravel()) + "\n"
                   for k in KEYS)


def write_calib(path: str | Path, calib: Calibration) -> None:
    atomic_write_text(path, format_calib(calib))


def read_calib(path: str | Path) -> Calibration:
    """Parse a 7-line KITTI calib file (keys may come in any order; `R_rect` is read as R0_rect)."""
    path = Path(path)
    values: dict[str, np.ndarray] = {}
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        key, sep, rest = line.partition(":")
        key = key.strip()
        if not sep:
            raise KittiFormatError("expected 'KEY: values'", path, lineno, key or "key")
        key = {"R_rect": "R0_rect", "Tr_velo_cam": "Tr_velo_to_cam",
               "Tr_imu_velo": "Tr_imu_to_velo"}.get(key, key)
        if key not in _SHAPES:
            continue
        toks = rest.split()
        n = int(np.prod(_SHAPES[key]))
        if len(toks) != n:
            raise KittiFormatError(f"expected {n} numbers, found {len(toks)}", path, lineno, key)
        try:
            values[key] = np.array([float(t) for t in toks]).reshape(_SHAPES[key])
        except ValueError:
            bad = next(t for t in toks if not _is_number(t))
            raise KittiFormatError(f"'{bad}' is not a number", path, lineno, key) from None
    for key in KEYS:
        if key not in values:
            raise KittiFormatError("missing key", path, None, key)
    return Calibration(**values)


def _is_number(tok: str) -> bool:
    try:
        float(tok)
        return True
    except ValueError:
        return False
