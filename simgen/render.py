"""Off-screen camera: colour, depth and instance ids of a world through its rig, with pyrender.

One OffscreenRenderer per worker process, reused across frames (EGL; Mesa's llvmpipe on a
machine without a GPU). Two passes per frame: a lit colour pass (4x MSAA) and a flat
segmentation pass without multisampling, sampled at pixel centres, whose 8-bit colours carry the
actor id exactly (id = R + 256 G) and whose depth buffer gives the depth image. Each actor is one draw call (its parts merged, colours per face);
the static world is one more.

Exact camera: the real KITTI rectified camera 2 is not a rigid transform of the world (R0_rect
times Tr_velo_to_cam is orthonormal only to ~1e-4). The camera node gets the nearest rigid pose
(for lighting) and the projection matrix absorbs the small residual, so every pixel lands where
P2 puts it. pyrender puts pixel centres at u + 0.5; KITTI at integer u: the principal point is
shifted by half a pixel to match.
"""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from dataclasses import dataclass  # noqa: E402

import numpy as np  # noqa: E402
import pyrender  # noqa: E402
from pyrender.constants import RenderFlags  # noqa: E402

from .meshes import EMISSIVE  # noqa: E402
from .world import Part, World  # noqa: E402

ZNEAR, ZFAR = 0.3, 400.0
_F = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenGL camera axes <-> computer-vision camera axes

SKY = {"day": (0.62, 0.74, 0.90), "dusk": (0.55, 0.42, 0.38), "night": (0.015, 0.015, 0.025)}
AMBIENT = {"day": 0.45, "dusk": 0.18, "night": 0.02}
SUN = {"day": (1.0, 0.97, 0.92), "dusk": (1.0, 0.62, 0.38), "night": (0.4, 0.45, 0.6)}
SUN_POWER = {"day": 4.0, "dusk": 2.0, "night": 0.08}

# Thermal emulation ("white hot", 0..1): a temperature per material; moving vehicles run warm.
TEMPERATURE = {"asphalt": 0.42, "marking": 0.40, "curb": 0.38, "sidewalk": 0.38, "verge": 0.30,
               "sand": 0.55, "forest_floor": 0.27, "facade": 0.33, "bark": 0.30, "foliage": 0.24,
               "pole": 0.28, "fence": 0.30,
               "paint": 0.45, "glass": 0.28, "tyre": 0.55, "plate": 0.42, "headlight": 0.80,
               "taillight": 0.70, "bike_frame": 0.40, "skin": 0.97, "clothes": 0.78, "user": 0.50}
_WARM_WHEN_MOVING = {"tyre": 0.30, "paint": 0.10}


@dataclass
class RenderOutput:
    color: np.ndarray  # (H, W, 3) uint8 RGB, before the weather/sensor look (simgen.look)
    depth: np.ndarray  # (H, W) float32 camera-2 z in metres, 0 where no surface
    instance: np.ndarray  # (H, W) uint16 actor id, 0 = background


class _ExactCamera(pyrender.IntrinsicsCamera):
    """An intrinsics camera whose projection also applies a fixed near-identity 4x4 residual."""

    def __init__(self, K: np.ndarray, residual_gl: np.ndarray):
        super().__init__(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2] + 0.5, cy=K[1, 2] + 0.5,
                         znear=ZNEAR, zfar=ZFAR)
        self.residual_gl = residual_gl

    def get_projection_matrix(self, width=None, height=None):
        return super().get_projection_matrix(width, height) @ self.residual_gl


_RENDERERS: dict[tuple[int, int, int], pyrender.OffscreenRenderer] = {}


def renderer(width: int, height: int) -> pyrender.OffscreenRenderer:
    """The process's renderer for this image size, created once. Keyed by process id too: a
    forked child must not reuse its parent's GL context."""
    key = (os.getpid(), width, height)
    if key not in _RENDERERS:
        _RENDERERS[key] = pyrender.OffscreenRenderer(width, height)
    return _RENDERERS[key]


def camera_node_pose(cam2_from_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(world-from-GL-camera rigid pose, GL residual) that together reproduce cam2_from_world."""
    U, _, Vt = np.linalg.svd(cam2_from_world[:3, :3])
    rigid = np.eye(4)
    rigid[:3, :3] = U @ Vt
    rigid[:3, 3] = cam2_from_world[:3, 3]
    residual_cv = cam2_from_world @ np.linalg.inv(rigid)
    return np.linalg.inv(rigid) @ _F, _F @ residual_cv @ _F


_PLAIN = pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0), metallicFactor=0.0,
                                            roughnessFactor=0.9, doubleSided=True)
# pyrender's diffuse term for a white base: (1 - F) c_diff / pi with F ~ 0.04, c_diff = 0.96.
_DIFFUSE = 0.96 * 0.96 / np.pi


def _flat_mesh(parts: list[Part], shader: "_Shader | None", rotation: np.ndarray, moving: bool,
               material=_PLAIN) -> pyrender.Mesh:
    """One flat-shaded primitive for many parts, a colour per face (vertices unshared per face);
    white faces without a shader (emissive lamps)."""
    tris, normals = _triangles(parts)
    face_colors = shader.colors(parts, normals @ rotation.T, moving) if shader else np.ones((len(tris), 3))
    prim = pyrender.Primitive(positions=tris.reshape(-1, 3).astype(np.float32),
                              normals=np.repeat(normals, 3, axis=0).astype(np.float32),
                              color_0=np.c_[np.repeat(face_colors, 3, axis=0), np.ones(3 * len(tris))
                                            ].astype(np.float32), material=material)
    return pyrender.Mesh([prim])


def _triangles(parts: list[Part]) -> tuple[np.ndarray, np.ndarray]:
    """(F, 3, 3) triangles and (F, 3) unit normals of all parts (numpy, no trimesh caches)."""
    tris = np.concatenate([np.asarray(p.mesh.vertices)[np.asarray(p.mesh.faces)] for p in parts])
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return tris, n


def _to_sun(light) -> np.ndarray:
    el, az = np.radians(light.sun_elevation_deg), np.radians(light.sun_azimuth_deg)
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


class _Shader:
    """Face colours for the three looks.

    'lit' (day, dusk): Lambertian sun plus a sky term brighter on upward faces, evaluated per
    face on the CPU and gamma-encoded, then drawn with pyrender's unlit shader: 5-7x faster
    on llvmpipe than its per-pixel PBR shader, and the same picture for flat-shaded diffuse
    surfaces. 'pbr' (night): albedo only; pyrender lights per pixel, as the headlamp cones
    need. 'thermal': a temperature per material, unlit.
    """

    def __init__(self, world: World):
        light = world.light
        self.mode = ("thermal" if world.sensor == "thermal"
                     else "pbr" if light.time == "night" else "lit")
        self.sun = _to_sun(light)
        self.sun_rgb = np.asarray(SUN[light.time]) * SUN_POWER[light.time] * light.sun_intensity
        self.ambient = AMBIENT[light.time]

    def colors(self, parts: list[Part], normals: np.ndarray, moving: bool) -> np.ndarray:
        """(F, 3) colours of all faces of the parts (world-frame normals), in _triangles order."""
        counts = [len(p.mesh.faces) for p in parts]
        if self.mode == "thermal":
            return np.repeat(np.array([_thermal(p, moving) for p in parts]), counts, axis=0)
        albedo = np.repeat(np.array([p.material.color for p in parts], float), counts, axis=0)
        if self.mode == "pbr":
            return albedo
        sun = np.clip(normals @ self.sun, 0.0, 1.0)[:, None] * self.sun_rgb * _DIFFUSE
        sky = self.ambient * (0.7 + 0.3 * normals[:, 2:3])
        return np.clip((albedo * (sun + sky)) ** (1 / 2.2), 0.0, 1.0)


def _thermal(part: Part, moving: bool) -> tuple[float, float, float]:
    t = TEMPERATURE.get(part.material.name, 0.35)
    if moving:
        t += _WARM_WHEN_MOVING.get(part.material.name, 0.0)
    return (t, t, t)


def build_scene(world: World) -> tuple[pyrender.Scene, dict, int]:
    """The pyrender scene of a world at t = 0, its segmentation map (node -> colour) and the
    render flags of its colour pass."""
    light = world.light
    shader = _Shader(world)
    scene = pyrender.Scene(bg_color=(*((0.02,) * 3 if shader.mode == "thermal" else SKY[light.time]), 1.0),
                           ambient_light=(AMBIENT[light.time],) * 3)
    seg: dict = {}
    if world.static:
        seg[scene.add(_flat_mesh(world.static, shader, np.eye(3), False))] = (0, 0, 0)
    lamps: list[tuple[Part, np.ndarray, tuple]] = []
    for actor in world.actors:
        moving = float(np.linalg.norm(actor.velocity)) > 0.5
        lit = shader.mode == "pbr" and moving  # night: moving vehicles' lamps glow; parked stay off
        body = [p for p in actor.parts if not (lit and p.material.name in EMISSIVE)]
        code = (actor.id % 256, actor.id // 256, 0)
        node = scene.add(_flat_mesh(body, shader, actor.pose[:3, :3], moving), pose=actor.pose)
        seg[node] = code
        lamps += [(p, actor.pose, code) for p in actor.parts if lit and p.material.name in EMISSIVE]
    for part, pose, code in lamps:
        mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=(0.0, 0.0, 0.0, 1.0),
                                                 emissiveFactor=EMISSIVE[part.material.name],
                                                 doubleSided=True)
        seg[scene.add(_flat_mesh([part], None, np.eye(3), True, mat), pose=pose)] = code
    rig = world.rig
    pose, residual = camera_node_pose(rig.cam2_from_world())
    scene.add(_ExactCamera(rig.intrinsics(), residual), pose=pose)
    if shader.mode == "pbr":
        z = shader.sun
        x = np.cross([0.0, 0.0, 1.0], z) if abs(z[2]) < 0.999 else np.array([1.0, 0.0, 0.0])
        x /= np.linalg.norm(x)
        sun_pose = np.eye(4)
        sun_pose[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
        scene.add(pyrender.DirectionalLight(color=SUN[light.time],
                                            intensity=SUN_POWER[light.time] * light.sun_intensity),
                  pose=sun_pose)
        for dy in (-0.6, 0.6):  # the ego vehicle's (or the gantry's) headlamps
            p = pose.copy()
            p[:3, 3] += pose[:3, :3] @ np.array([dy, -0.9, 0.0])
            scene.add(pyrender.SpotLight(color=(1.0, 0.95, 0.85), intensity=800.0,
                                         innerConeAngle=0.15, outerConeAngle=0.45), pose=p)
    return scene, seg, RenderFlags.NONE if shader.mode == "pbr" else RenderFlags.FLAT


def render(world: World) -> RenderOutput:
    rig = world.rig
    r = renderer(rig.width, rig.height)
    scene, seg, flags = build_scene(world)
    color, _ = r.render(scene, flags=flags)
    # Depth from the single-sample pass: the multisampled pass's depth is that of sample 0, a
    # third of a pixel off the pixel centre.
    ids, depth = r.render(scene, flags=RenderFlags.SEG, seg_node_map=seg)
    instance = ids[..., 0].astype(np.uint16) + 256 * ids[..., 1].astype(np.uint16)
    return RenderOutput(np.ascontiguousarray(color[..., :3]), depth.astype(np.float32), instance)
