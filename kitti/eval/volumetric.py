"""The volumetric metrics of the tolling thesis (M. Fornes, "Monocular 3D Object Detection for
Volumetric Identification in the Tolling Industry", NTNU 2023), on matched truth/detection pairs.

Per pair: size precision `P_dim = (1 - sum_{l,w,h} |k^ - k| / k) * 100 %`, size error
`E_dim = sum |k^ - k|`; location precision `P_loc = (1 - sum_{ground axes} |c^ - c| / (D/2)) * 100 %`,
location error `E_loc = sum |c^ - c|`; then means over pairs, with the per-axis mean absolute errors
L, W, H, XC, YC, ZC.

Axes: 004 works in a road frame with z up, so its XC, YC lie on the ground and ZC is the height.
In KITTI's rectified camera frame the ground axes are x (across) and z (ahead) and the vertical
is y, hence XC = |dx|, YC = |dz|, ZC = |dy| of the geometric box centres (location minus h/2 in y).
D is the sensor's maximum perceived distance (default 80 m, KITTI's usual evaluation range).
"""

from __future__ import annotations

import numpy as np

DEFAULT_MAX_DISTANCE = 80.0


def centres(box7: np.ndarray) -> np.ndarray:
    """(N, 3) geometric centres from bottom-centre boxes."""
    c = box7[:, :3].copy()
    c[:, 1] -= box7[:, 3] / 2
    return c


def volumetric(gt7: np.ndarray, dt7: np.ndarray, max_distance: float = DEFAULT_MAX_DISTANCE) -> dict:
    """004 metrics over matched pairs (row k of `gt7` with row k of `dt7`); None entries if empty."""
    keys = ("n", "size_precision", "location_precision", "size_error", "location_error",
            "L", "W", "H", "XC", "YC", "ZC")
    if len(gt7) == 0:
        return {k: (0 if k == "n" else None) for k in keys}
    dh, dw, dl = (np.abs(dt7[:, k] - gt7[:, k]) for k in (3, 4, 5))
    rel = dh / gt7[:, 3] + dw / gt7[:, 4] + dl / gt7[:, 5]
    d = np.abs(centres(dt7) - centres(gt7))
    ground = d[:, 0] + d[:, 2]
    return {"n": int(len(gt7)),
            "size_precision": float(np.mean((1 - rel) * 100)),
            "location_precision": float(np.mean((1 - ground / (max_distance / 2)) * 100)),
            "size_error": float(np.mean(dh + dw + dl)),
            "location_error": float(np.mean(ground)),
            "L": float(dl.mean()), "W": float(dw.mean()), "H": float(dh.mean()),
            "XC": float(d[:, 0].mean()), "YC": float(d[:, 2].mean()), "ZC": float(d[:, 1].mean())}
