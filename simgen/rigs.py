"""Camera rigs: where the camera is, as a KITTI Calibration plus a world-from-reference pose.

The reference frame of every rig is KITTI's "velodyne" frame (x forward, y left, z up):
- onboard: KITTI's calibration; the LiDAR 1.73 m above the road, tilted as the calibration says
  (kitti_lidar_tilt), so that the rectified camera is level.
- gantry (004): a camera at height h looking along the road, pan theta, tilt phi, one focal
  length f, principal point at the image centre; R = Rx(phi) Rz(theta) in 004's frame
  (x right, y along the road, z up), i.e. rows (cos t, -sin t, 0), (-sin p sin t, -sin p cos t,
  -cos p), (cos p sin t, cos p cos t, -sin p). Positive pan turns the view to the right,
  positive tilt looks down. Its reference frame sits at the camera centre with world axes, so
  Tr_velo_to_cam = [R | 0], R0_rect = I, P2 = [K | 0]; the road plane file gives the height.
- orbit (003): a camera at distance, elevation and azimuth from a target vehicle's centre,
  looking at it (azimuth 0 = in front of the target, 90 = on its left); reference frame as for
  the gantry.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kitti.calib import Calibration

KITTI_LIDAR_HEIGHT = 1.73
KITTI_IMAGE_SIZE = (1242, 375)
# Our world (x forward, y left, z up) to 004's (x right, y forward, z up).
_OURS_TO_004 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class CameraRig:
    """The camera of one frame: its calibration, image size and world-from-reference pose."""

    kind: str
    calib: Calibration
    width: int
    height: int
    reference_pose: np.ndarray  # (4, 4) world-from-reference ("velodyne") frame
    params: dict = field(default_factory=dict)  # the sampled rig parameters, for meta/

    def cam2_from_world(self) -> np.ndarray:
        """(4, 4) exact map from world to camera-2 coordinates (x right, y down, z forward).

        It is T(t2) R0_rect Tr_velo_to_cam inv(reference_pose), with t2 = K^-1 P2[:, 3] the
        camera-2 offset from the rectified camera 0; not exactly rigid for the real KITTI
        numbers, which the renderer honours (simgen.render).
        """
        P2 = self.calib.P2
        K = P2[:, :3]
        t2 = np.linalg.solve(K, P2[:, 3])
        T = np.eye(4)
        T[:3, 3] = t2
        return T @ self.calib.velo_to_rect @ np.linalg.inv(self.reference_pose)

    def intrinsics(self) -> np.ndarray:
        return self.calib.P2[:, :3]

    def road_plane_rect(self, plane_world: np.ndarray | None = None) -> np.ndarray:
        """A world plane (a, b, c, d) (default: the flat road z = 0) in rect camera coords, unit
        normal pointing up."""
        if plane_world is None:
            plane_world = np.array([0.0, 0.0, 1.0, 0.0])
        rect_from_world = self.calib.velo_to_rect @ np.linalg.inv(self.reference_pose)
        p = np.linalg.inv(rect_from_world).T @ plane_world
        return p / np.linalg.norm(p[:3])


# LiDAR (x forward, y left, z up) to rectified camera (x right, y down, z forward) axes.
_VELO_TO_RECT_AXES = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


def kitti_lidar_tilt(calib: Calibration) -> np.ndarray:
    """The LiDAR's orientation on a car whose rectified camera is level: the rotation E nearest to
    A^-1 R0_rect Tr_velo_to_cam, A the pure axis swap (KITTI's printed numbers are rigid to 2e-8).

    KITTI's rectified camera looks level along the road (the labels' boxes are yaw-only in it, and
    the road planes fitted to the dev frames' scans rise by -0.1 deg ahead in it, median of 11),
    and its calibration tilts the LiDAR about 0.85 deg from the camera's vertical: on the
    2011_09_26 drives the LiDAR's forward axis points 0.60 deg below the camera's horizon and its
    left axis 0.61 deg below, so a level road rises 0.6 deg ahead of the sensor in its scans (0.69
    deg, median of the dev frames' fitted planes)."""
    u, _, vt = np.linalg.svd(_VELO_TO_RECT_AXES.T @ calib.R0_rect @ calib.Tr_velo_to_cam[:, :3])
    return u @ vt


def onboard_rig(lidar_mount: tuple[float, float, float] = (0.0, 0.0, KITTI_LIDAR_HEIGHT)) -> CameraRig:
    """KITTI's car: the LiDAR at `lidar_mount` (world, above the road under the ego origin),
    tilted as KITTI's calibration of the 2011_09_26 drives says (kitti_lidar_tilt), and the
    cameras where that calibration puts them. Its Tr_velo_to_cam is written exactly rigid,
    R0_rect^-1 [A E | R0_rect t] with KITTI's t (it moves by under 2e-8), so the rectified
    camera is exactly level: world vertical is its -y axis, and upright actors fit KITTI's
    yaw-only boxes exactly."""
    real = Calibration.kitti_default()
    tilt = kitti_lidar_tilt(real)
    t_rect = real.R0_rect @ real.Tr_velo_to_cam[:, 3]
    tr = np.linalg.inv(real.R0_rect) @ np.c_[_VELO_TO_RECT_AXES @ tilt, t_rect]
    calib = Calibration(real.P0, real.P1, real.P2, real.P3, real.R0_rect, tr, real.Tr_imu_to_velo)
    ref = np.eye(4)
    ref[:3, :3] = tilt
    ref[:3, 3] = lidar_mount
    w, h = KITTI_IMAGE_SIZE
    return CameraRig("onboard", calib, w, h, ref, {"lidar_height": float(lidar_mount[2])})


def pinhole_calibration(R_cam_from_ref: np.ndarray, focal: float, width: int, height: int) -> Calibration:
    """One camera, one focal length, principal point at the image centre, reference at its centre."""
    P = np.array([[focal, 0.0, width / 2.0, 0.0], [0.0, focal, height / 2.0, 0.0], [0, 0, 1.0, 0]])
    Tr = np.zeros((3, 4))
    Tr[:, :3] = R_cam_from_ref
    return Calibration(P0=P, P1=P, P2=P, P3=P, R0_rect=np.eye(3), Tr_velo_to_cam=Tr,
                       Tr_imu_to_velo=np.eye(4)[:3])


def gantry_rotation(pan_deg: float, tilt_deg: float) -> np.ndarray:
    """Camera-from-world rotation of the 004 model, for our world axes."""
    t, p = np.radians(pan_deg), np.radians(tilt_deg)
    R004 = np.array([[np.cos(t), -np.sin(t), 0.0],
                     [-np.sin(p) * np.sin(t), -np.sin(p) * np.cos(t), -np.cos(p)],
                     [np.cos(p) * np.sin(t), np.cos(p) * np.cos(t), -np.sin(p)]])
    return R004 @ _OURS_TO_004


def look_at_rotation(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Camera-from-world rotation of a level camera (no roll) at eye looking at target."""
    f = np.asarray(target, float) - np.asarray(eye, float)
    f /= np.linalg.norm(f)
    x = np.cross(f, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(f, x)
    return np.stack([x, y, f])


def gantry_rig(cam_height: float, pan_deg: float, tilt_deg: float, focal_px: float,
               position_xy: tuple[float, float], width: int, height: int) -> CameraRig:
    ref = np.eye(4)
    ref[:3, 3] = [position_xy[0], position_xy[1], cam_height]
    calib = pinhole_calibration(gantry_rotation(pan_deg, tilt_deg), focal_px, width, height)
    return CameraRig("gantry", calib, width, height, ref,
                     {"cam_height": cam_height, "pan_deg": pan_deg, "tilt_deg": tilt_deg,
                      "focal_px": focal_px, "position_xy": list(position_xy)})


def orbit_rig(target_centre: np.ndarray, distance: float, elevation_deg: float, azimuth_deg: float,
              focal_px: float, width: int, height: int) -> CameraRig:
    e, a = np.radians(elevation_deg), np.radians(azimuth_deg)
    target_centre = np.asarray(target_centre, float)
    eye = target_centre + distance * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    ref = np.eye(4)
    ref[:3, 3] = eye
    calib = pinhole_calibration(look_at_rotation(eye, target_centre), focal_px, width, height)
    return CameraRig("orbit", calib, width, height, ref,
                     {"distance": distance, "elevation_deg": elevation_deg,
                      "azimuth_deg": azimuth_deg, "focal_px": focal_px,
                      "target_centre": target_centre.tolist()})
