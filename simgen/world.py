"""The world: the single source of truth every label, image and LiDAR point derives from.

World frame: right-handed, metres, x forward along the ego lane, y left, z up, the road
surface at z = 0 under the ego vehicle. Time t = 0 is the camera trigger, which is also
the instant the rotating LiDAR faces forward (as in KITTI); a sweep spans
[-T/2, T/2] for rotation period T.

Actor frame: origin at the bottom-face centre of the actor's 3D box, x along its length
(forward), y along its width (left), z up. The label box is the exact extent of the
actor's mesh in this frame.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
import trimesh


@dataclass(frozen=True)
class Material:
    """Surface look for the camera and the LiDAR (the 905 nm values and their sources:
    `simgen.materials`; what the sensor makes of them: `simgen.lidar.scan`)."""

    name: str
    color: tuple[float, float, float]  # linear RGB in [0, 1]
    # The LiDAR reading at normal incidence: the diffuse reflectivity at 905 nm, in [0, 1]; above 1
    # for retro-reflectors (pi x their coefficient of retroreflection, which saturates the reading).
    reflectivity: float
    # The reading falls as cos(incidence) ** incidence_exponent: 1 Lambertian; 0 for dark rough
    # ground (Lommel-Seeliger: no fall-off in the backscatter direction) and leaf volumes.
    incidence_exponent: float = 1.0
    porosity: float = 0.0  # share of the rays hitting it that pass on (gaps between leaves)
    # Glass: one-way power transmittance of a pane at normal incidence at 905 nm. > 0 makes the
    # part a closed glass solid that every beam passes (a pane's own echo is never reported); what
    # lies behind returns with the two-way loss, and `reflectivity` is the vehicle interior's, for
    # a beam that ends inside (simgen.lidar.scan).
    transmittance: float = 0.0


class PartMesh:
    """An actor part's vertices and faces: all that the camera, the LiDAR and the labels read of
    it. Anything else (bounds, volume, unique edges, ...) comes from a trimesh made on first use:
    making one for each of the ~1,600 parts of a frame's actors cost about 80 ms of its 450 ms
    of world sampling."""

    __slots__ = ("vertices", "faces", "_mesh")

    def __init__(self, vertices, faces):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)  # trimesh's index type
        self._mesh = None

    @property
    def trimesh(self) -> trimesh.Trimesh:
        if self._mesh is None:
            self._mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        return self._mesh

    def __getattr__(self, name: str):
        if name.startswith("_"):  # copy and pickle probe an instance before its slots are set
            raise AttributeError(name)
        return getattr(self.trimesh, name)


@dataclass
class Part:
    """One mesh with one material, in its owner's frame (actor frame or world frame)."""

    mesh: trimesh.Trimesh | PartMesh
    material: Material


@dataclass(frozen=True)
class Weather:
    """One weather model per world, shared by the camera and the LiDAR.

    fog_extinction is the atmospheric extinction coefficient beta (1/m); the
    meteorological visibility is about 3 / beta. Light through fog falls as
    exp(-beta d) one way, a LiDAR return as exp(-2 beta d). rain_rate in mm/h, wind in m/s.
    """

    fog_extinction: float = 0.0
    rain_rate: float = 0.0
    wind: float = 0.0

    @property
    def visibility(self) -> float:
        return float("inf") if self.fog_extinction <= 0 else 3.0 / self.fog_extinction


@dataclass(frozen=True)
class Light:
    """Sun and time of day. Azimuth from world +x towards +y, elevation above the horizon."""

    time: str = "day"  # day, dusk or night
    sun_intensity: float = 1.0  # share of full sun
    sun_elevation_deg: float = 45.0
    sun_azimuth_deg: float = 30.0


@dataclass(frozen=True)
class Appearance:
    """What the camera sees of surfaces and sky beyond their flat colour (simgen.render): the
    procedural textures (simgen.textures), sun shadows, the share of the sky under cloud, and a
    per-frame spread of the scenery's colours (log-normal sd of each channel's gain)."""

    textures: bool = True
    shadows: bool = True
    cloud_cover: float = 0.3
    colour_jitter: float = 0.08


@dataclass(frozen=True)
class CameraResponse:
    """The colour camera between the light and the 8-bit image (simgen.camera)."""

    exposure_ev: float = 0.0  # offset from the auto-exposure (log-average luminance to 0.18)
    white_balance_sd: float = 0.03  # log sd of the red and blue gains against green
    corner_illumination: float = 0.75  # vignetting: relative illumination at the image corner
    blur_sigma_px: float = 0.0  # the lens, a Gaussian of this sd in output pixels (spec.CameraSpec)
    full_well_e: float = 10000.0  # electrons at the white level (shot noise); 0 = no noise
    read_noise_e: float = 10.0
    bayer: bool = True  # sample through an RGGB colour filter array, then demosaic
    # the colour filter array on KITTI's raw pixels (distorted, finer), then rectified back
    # (bilinear) as KITTI's frames are; False: on the output's own pixels (simgen.camera)
    rectified: bool = True
    gamma: float = 1.4  # output curve, value = signal ** (1 / gamma); KITTI-like (camera.KEY)


@dataclass
class Actor:
    """A labelled object: parts in its own frame, a pose at t = 0 and a constant motion."""

    id: int  # > 0 and unique in its world; 0 means background
    cls: str  # KITTI type: Car, Van, Truck, Pedestrian, Cyclist, Tram, Misc (Bus for roadside)
    parts: list[Part]
    pose: np.ndarray  # (4, 4) world-from-actor at t = 0
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # world frame, m/s
    yaw_rate: float = 0.0  # rad/s about world z
    # How the parts were built (simgen.meshes.build_actor_parts), so meta/ can rebuild them.
    recipe: dict = field(default_factory=dict)
    stop_lamps: bool = False  # lit: the vehicle brakes (simgen.render draws them by day)

    @property
    def moving(self) -> bool:
        """Faster than 0.5 m/s: a vehicle whose lamps glow at night and that may brake by day."""
        return float(np.linalg.norm(self.velocity)) > 0.5

    def pose_at(self, t: float | np.ndarray) -> np.ndarray:
        """World-from-actor pose(s) at time t under constant velocity and yaw rate.

        Returns (4, 4) for scalar t and (N, 4, 4) for an array of times.
        """
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        poses = np.repeat(self.pose[None], len(ts), axis=0)
        if self.yaw_rate != 0.0:
            a = self.yaw_rate * ts
            c, s = np.cos(a), np.sin(a)
            rz = np.zeros((len(ts), 3, 3))
            rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1], rz[:, 2, 2] = c, -s, s, c, 1.0
            poses[:, :3, :3] = rz @ self.pose[:3, :3]
        poses[:, :3, 3] += ts[:, None] * np.asarray(self.velocity)[None, :]
        return poses[0] if np.ndim(t) == 0 else poses

    def mesh(self) -> trimesh.Trimesh:
        """All parts concatenated, in the actor frame."""
        return trimesh.util.concatenate([getattr(p.mesh, "trimesh", p.mesh) for p in self.parts])


@dataclass
class World:
    """Actors, static scenery and the ego sensors' motion; everything else is derived.

    lidar_pose is world-from-LiDAR at t = 0 (LiDAR frame: x forward, y left, z up).
    The ego vehicle (and with it every sensor) moves with ego_velocity (world frame).
    """

    actors: list[Actor]
    static: list[Part]  # road, markings, curbs, buildings, trees, poles, fences: world frame
    weather: Weather
    lidar_pose: np.ndarray
    ego_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    # Added by the scene generator: the camera (simgen.rigs.CameraRig), light, sensor look, the
    # parameters that rebuild `static` (simgen.scenery.build_scenery), and where it came from.
    rig: object | None = None
    light: Light = field(default_factory=Light)
    appearance: Appearance = field(default_factory=Appearance)
    camera: CameraResponse = field(default_factory=CameraResponse)
    sensor: str = "normal"  # normal, night_vision or thermal
    scenery: dict = field(default_factory=dict)
    seed: int = 0
    frame_index: int = 0

    def lidar_pose_at(self, t: float | np.ndarray) -> np.ndarray:
        """World-from-LiDAR pose(s) of the moving ego sensor at time t."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        poses = np.repeat(self.lidar_pose[None], len(ts), axis=0)
        poses[:, :3, 3] += ts[:, None] * np.asarray(self.ego_velocity)[None, :]
        return poses[0] if np.ndim(t) == 0 else poses

    def actor(self, actor_id: int) -> Actor:
        for a in self.actors:
            if a.id == actor_id:
                return a
        raise KeyError(f"no actor with id {actor_id}")


def fit_parts(parts: list[Part], h: float, w: float, l: float) -> list[Part]:
    """Scale and shift parts so their joint extent is exactly l x w x h, origin at the bottom centre.

    The parts' meshes may be trimeshes or anything with vertices and faces (simgen.meshes.Shape);
    the result holds PartMeshes. All vertices are moved in one array operation: elementwise, so
    every vertex gets the bits it would get part by part."""
    verts = [np.asarray(p.mesh.vertices) for p in parts]
    allv = np.concatenate(verts)
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    scale = np.array([l, w, h]) / (hi - lo)
    shift = np.array([l / 2, w / 2, 0.0])
    fitted = (allv - lo) * scale - shift
    ends = list(itertools.accumulate(len(v) for v in verts))
    return [Part(PartMesh(fitted[a:b], p.mesh.faces), p.material)
            for p, a, b in zip(parts, [0, *ends[:-1]], ends)]
