"""Does the ego's motion during the exposure explain KITTI's soft near road? (a diagnosis)

The fidelity report finds the generated road surface's fine detail twice KITTI's at 5-10 m and
alike at 10-20 m (`images.road_surface_detail_*`). Motion blur would do that: KITTI's cameras are
triggered by the scanner "with shutter time adjusted dynamically (maximum shutter time: 2 ms)"
(KITTI raw data page), and a road point at ground distance Z, Δv rows below the horizon, moves
Δv · speed · t / Z pixels during an exposure t of a camera driving forward at `speed`: about half
a pixel at 7 m and 10 m/s, a tenth at 15 m. This blurs generated frames by exactly that flow
(every pixel along its own line, from depth_2 and the ego's speed in meta/; static world, the
frame's camera P2) at the longest shutter KITTI allows, and reads the road-surface statistics
before and after (`testbed.fidelity`'s own functions, the scan's road returns as the report
picks them). The blur is applied to the finished 8-bit image, after the camera's noise and
demosaicing, where the physical blur acts before them: an upper bound on what it does to the
texture, a slight overstatement of what it does to the noise.

    .venv/bin/python benchmarks/motion_blur_road.py --data data/s49/urban200_regen --frames 60 [--shutter-ms 2]
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np
from tqdm import tqdm

from kitti.dataset import KittiDataset
from kitti.derived import read_json
from testbed.fidelity.images import road_surface_stats
from testbed.fidelity.lidar import lidar_stats
from testbed.fidelity.stats import Acc

KEYS = ("images.road_surface_detail_5_10m", "images.road_surface_detail_10_20m",
        "images.road_surface_colour_noise_5_10m", "images.road_surface_colour_noise_10_20m")
TAPS = 9  # samples along each pixel's path (the path is at most a few pixels long)
CAMERA_HEIGHT_M = 1.65  # KITTI's colour cameras above the road: for the printed blur at 7 m only


def motion_blurred(img: np.ndarray, depth: np.ndarray, P: np.ndarray, speed: float,
                   shutter_s: float) -> np.ndarray:
    """`img` (BGR uint8) blurred by a forward translation of the camera at `speed` (m/s) over the
    exposure: pixel (u, v) at depth Z moves (u - cx, v - cy) · speed · t / Z; each output pixel is
    the mean of TAPS samples along its path, centred on it."""
    f = img.astype(np.float32)
    h, w = depth.shape
    z = np.where(depth > 0, depth, np.inf).astype(np.float32)
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    s = np.float32(speed * shutter_s) / z
    du, dv = (u - np.float32(P[0, 2])) * s, (v - np.float32(P[1, 2])) * s
    out = np.zeros_like(f)
    for a in np.linspace(-0.5, 0.5, TAPS, dtype=np.float32):
        out += cv2.remap(f, u + a * du, v + a * dv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return np.clip(np.round(out / TAPS), 0, 255).astype(np.uint8)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="a generated root (depth_2/ and meta/)")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--shutter-ms", type=float, default=2.0)
    args = ap.parse_args()
    ds = KittiDataset(args.data)
    before, after, blur_px = Acc(), Acc(), []
    for fid in tqdm(ds.ids(None)[: args.frames], desc="frames"):
        img = cv2.imread(str(ds.image_path(fid)))
        depth = cv2.imread(str(ds.path("depth_2", fid, "png")), cv2.IMREAD_UNCHANGED) / 256.0
        calib, meta = ds.calib(fid), read_json(ds.path("meta", fid, "json"))
        speed = float(np.hypot(*meta["ego_velocity"][:2]))
        blurred = motion_blurred(img, depth, calib.P2, speed, args.shutter_ms / 1000.0)
        before.frames.append(fid)
        after.frames.append(fid)
        road = lidar_stats(before, ds.velodyne(fid), calib, None)  # the scan's road, read once
        if road is not None:
            for acc, im in ((before, img), (after, blurred)):
                road_surface_stats(acc, im, cv2.cvtColor(im, cv2.COLOR_BGR2GRAY), *road, calib)
        below = calib.P2[1, 1] * CAMERA_HEIGHT_M / 7.0  # rows below the horizon of the road 7 m ahead
        blur_px.append(speed * args.shutter_ms / 1000.0 * below / 7.0)
    print(f"{args.data}: {len(before.frames)} frames, shutter {args.shutter_ms:g} ms, ego speed as in "
          f"meta/; the road 7 m ahead blurred a median {np.median(blur_px):.2f} px along the image's "
          f"column (max {np.max(blur_px):.2f})")
    print("| statistic (median over frames) | as generated | motion-blurred |")
    print("|---|---:|---:|")
    for key in KEYS:
        a, b = (np.median(np.concatenate(acc.values[key])) for acc in (before, after))
        print(f"| `{key}` | {a:.2f} | {b:.2f} |")


if __name__ == "__main__":
    main()
