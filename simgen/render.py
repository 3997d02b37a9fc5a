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
               "facade": 0.33, "bark": 0.30, "foliage": 0.24, "pole": 0.28, "fence": 0.30,
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


_RENDERERS: dict[tuple[int, int], pyrender.OffscreenRenderer] = {}


def renderer(width: int, height: int) -> pyrender.OffscreenRenderer:
    """The process's renderer for this image size, created once."""
    key = (width, height)
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


def _flat_mesh(parts: list[Part], colors: list, material=_PLAIN) -> pyrender.Mesh:
    """One flat-shaded primitive for many parts, a colour per part (vertices unshared per face)."""
    tris = [p.mesh.vertices[p.mesh.faces] for p in parts]  # (F, 3, 3) each
    pos = np.concatenate(tris).reshape(-1, 3)
    normals = np.concatenate([np.repeat(p.mesh.face_normals, 3, axis=0) for p in parts])
    col = np.concatenate([np.tile(np.asarray(c, np.float32), (3 * len(t), 1))
                          for c, t in zip(colors, tris)])
    prim = pyrender.Primitive(positions=pos.astype(np.float32), normals=normals.astype(np.float32),
                              color_0=np.c_[col, np.ones(len(col), np.float32)], material=material)
    return pyrender.Mesh([prim])


def _thermal(part: Part, moving: bool) -> tuple[float, float, float]:
    t = TEMPERATURE.get(part.material.name, 0.35)
    if moving:
        t += _WARM_WHEN_MOVING.get(part.material.name, 0.0)
    return (t, t, t)


def build_scene(world: World) -> tuple[pyrender.Scene, dict]:
    """The pyrender scene of a world at t = 0 and its segmentation map (node -> colour)."""
    light = world.light
    time = light.time
    thermal = world.sensor == "thermal"
    scene = pyrender.Scene(bg_color=(*((0.02,) * 3 if thermal else SKY[time]), 1.0),
                           ambient_light=(AMBIENT[time],) * 3)
    seg: dict = {}
    night = time == "night" and not thermal
    static_colors = [_thermal(p, False) if thermal else p.material.color for p in world.static]
    if world.static:
        seg[scene.add(_flat_mesh(world.static, static_colors))] = (0, 0, 0)
    lamps: dict[str, list[tuple[Part, np.ndarray, tuple]]] = {}
    for actor in world.actors:
        moving = float(np.linalg.norm(actor.velocity)) > 0.5
        lit = night and moving  # parked cars keep their lamps off
        body = [p for p in actor.parts if not (lit and p.material.name in EMISSIVE)]
        colors = [_thermal(p, moving) if thermal else p.material.color for p in body]
        code = (actor.id % 256, actor.id // 256, 0)
        seg[scene.add(_flat_mesh(body, colors), pose=actor.pose)] = code
        if lit:
            for p in actor.parts:
                if p.material.name in EMISSIVE:
                    lamps.setdefault(p.material.name, []).append((p, actor.pose, code))
    for name, items in lamps.items():
        mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=(0.0, 0.0, 0.0, 1.0),
                                                 emissiveFactor=EMISSIVE[name], doubleSided=True)
        for part, pose, code in items:
            seg[scene.add(_flat_mesh([part], [(1.0, 1.0, 1.0)], mat), pose=pose)] = code
    rig = world.rig
    pose, residual = camera_node_pose(rig.cam2_from_world())
    scene.add(_ExactCamera(rig.intrinsics(), residual), pose=pose)
    if not thermal:
        el, az = np.radians(light.sun_elevation_deg), np.radians(light.sun_azimuth_deg)
        to_sun = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        z = to_sun
        x = np.cross([0.0, 0.0, 1.0], z) if abs(z[2]) < 0.999 else np.array([1.0, 0.0, 0.0])
        x /= np.linalg.norm(x)
        sun_pose = np.eye(4)
        sun_pose[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
        scene.add(pyrender.DirectionalLight(color=SUN[time],
                                            intensity=SUN_POWER[time] * light.sun_intensity),
                  pose=sun_pose)
        if time == "night":  # the ego vehicle's (or the gantry's) headlamps
            for dy in (-0.6, 0.6):
                p = pose.copy()
                p[:3, 3] += pose[:3, :3] @ np.array([dy, -0.9, 0.0])
                scene.add(pyrender.SpotLight(color=(1.0, 0.95, 0.85), intensity=800.0,
                                             innerConeAngle=0.15, outerConeAngle=0.45), pose=p)
    return scene, seg


def render(world: World) -> RenderOutput:
    rig = world.rig
    r = renderer(rig.width, rig.height)
    scene, seg = build_scene(world)
    flags = RenderFlags.FLAT if world.sensor == "thermal" else RenderFlags.NONE
    color, _ = r.render(scene, flags=flags)
    # Depth from the single-sample pass: the multisampled pass's depth is that of sample 0, a
    # third of a pixel off the pixel centre.
    ids, depth = r.render(scene, flags=RenderFlags.SEG, seg_node_map=seg)
    instance = ids[..., 0].astype(np.uint16) + 256 * ids[..., 1].astype(np.uint16)
    return RenderOutput(np.ascontiguousarray(color[..., :3]), depth.astype(np.float32), instance)
