"""Sun shadows for the camera, cast by the very meshes the LiDAR sees (Embree ray casting).

For every visible surface point (back-projected from the depth image) one ray goes towards
the sun; a point whose ray meets a mesh lies in shadow. Rays are cast on a grid of every
STEP-th pixel and the mask is upsampled bilinearly: the sun's disc (0.53 deg) gives real
shadows a penumbra of about 1 cm per metre between the caster and the ground, a few pixels for
the casters near the camera, so the soft edge of the upsampling (and of a slight blur that hides
the grid's stair steps) is no worse than the real one.

Leaves let sunlight through: a crown's closed mesh is crossed twice by a ray, and urban
broadleaf crowns pass 10-30 % of direct sun (simgen.materials, FOLIAGE), so a shadow cast by a
porous part is (1 - porosity ** 2) deep.
"""

from __future__ import annotations

import cv2
import numpy as np
from embreex.mesh_construction import TriangleMesh
from embreex.rtcore_scene import EmbreeScene

from .world import World

STEP = 3  # pixels between shadow rays
SOFTEN = 0.8  # ray-grid cells: a Gaussian that hides the grid's stair steps along shadow edges
T_NEAR = 0.05  # m: a ray starts this far from its surface point (depth precision, flat facets)


def _arr(a) -> np.ndarray:
    """A plain ndarray view of a trimesh TrackedArray (skips its per-access hashing)."""
    return np.asarray(a).view(np.ndarray)


def _scene(world: World) -> tuple[EmbreeScene, np.ndarray]:
    """An Embree scene of every triangle of the world at t = 0 and each triangle's shadow depth."""
    verts, faces, depth, n = [], [], [], 0
    for part, pose in [(p, None) for p in world.static] + [(p, a.pose) for a in world.actors for p in a.parts]:
        v = _arr(part.mesh.vertices)
        if pose is not None:
            v = v @ pose[:3, :3].T + pose[:3, 3]
        f = _arr(part.mesh.faces)
        verts.append(v)
        faces.append(f + n)
        n += len(v)
        depth.append(np.full(len(f), 1.0 - part.material.porosity ** 2, np.float32))
    scene = EmbreeScene()
    TriangleMesh(scene, np.concatenate(verts).astype(np.float32), np.concatenate(faces).astype(np.int32))
    return scene, np.concatenate(depth)


def sun_shadow(world: World, depth: np.ndarray, K: np.ndarray, cam2_from_world: np.ndarray,
               to_sun: np.ndarray, sunlit: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32 shadow depth in [0, 1] per pixel (0 = in sun), 0 where depth is 0 (sky).
    `sunlit` (H, W) bool, if given, limits the rays to pixels whose surface faces the sun (a
    shadow changes nothing on the others)."""
    H, W = depth.shape
    v, u = np.mgrid[STEP // 2:H:STEP, STEP // 2:W:STEP]
    z = depth[v, u]
    need = z > 0
    if sunlit is not None:
        need &= sunlit[v, u]
    small = np.zeros(z.shape, np.float32)
    if not need.any() or to_sun[2] <= 0:
        return np.zeros((H, W), np.float32)
    zc = z[need].astype(np.float64)
    cam = np.stack([(u[need] - K[0, 2]) * zc / K[0, 0], (v[need] - K[1, 2]) * zc / K[1, 1], zc,
                    np.ones_like(zc)])
    points = (np.linalg.inv(cam2_from_world) @ cam)[:3].T
    scene, strength = _scene(world)
    origins = (points + T_NEAR * to_sun).astype(np.float32)
    dirs = np.broadcast_to(to_sun.astype(np.float32), origins.shape).copy()
    prim = scene.run(origins, dirs)
    small[need] = np.where(prim >= 0, strength[np.maximum(prim, 0)], 0.0)
    small = cv2.GaussianBlur(small, (0, 0), SOFTEN)
    return cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR) * (depth > 0)
