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

from dataclasses import dataclass

import cv2
import numpy as np
from embreex.mesh_construction import TriangleMesh
from embreex.rtcore_scene import EmbreeScene

from .world import Part

STEP = 3  # pixels between shadow rays
SOFTEN = 0.8  # ray-grid cells: a Gaussian that hides the grid's stair steps along shadow edges
T_NEAR = 0.05  # m: a ray starts this far from its surface point (depth precision, flat facets)


@dataclass
class Occluders:
    """World-frame triangles that can cast a shadow, and each one's shadow depth."""

    tris: np.ndarray  # (F, 3, 3) float32
    depth: np.ndarray  # (F,) float32, 1 - porosity ** 2
    # The same triangles as shared vertices and faces (vertices[faces] equals tris bit for bit),
    # where known: embreex copies into Embree one Python-level read per coordinate, and shared
    # vertices are about a fifth of the triangles' corners.
    vertices: np.ndarray | None = None  # (V, 3) float32
    faces: np.ndarray | None = None  # (F, 3) int32

    @staticmethod
    def of_parts(parts: list[Part], tris: np.ndarray,
                 shared: tuple[np.ndarray, np.ndarray] | None = None) -> Occluders:
        """The parts' triangles (already in the world frame, in part order). `shared`, if given:
        the same triangles as (vertices, faces), faces indexing the vertices; kept only where
        they give `tris` exactly."""
        depth = np.repeat([1.0 - p.material.porosity ** 2 for p in parts],
                          [len(p.mesh.faces) for p in parts]).astype(np.float32)
        tris = np.asarray(tris, np.float32).reshape(-1, 3, 3)
        if shared is None:
            return Occluders(tris, depth)
        vertices, faces = np.asarray(shared[0], np.float32), np.asarray(shared[1], np.int32)
        if faces.shape != (len(tris), 3) or not np.array_equal(vertices[faces], tris):
            return Occluders(tris, depth)
        return Occluders(tris, depth, vertices, faces)

    @staticmethod
    def join(a: Occluders, b: Occluders) -> Occluders:
        if not len(a.tris) or not len(b.tris):
            return b if not len(a.tris) else a
        if a.faces is None or b.faces is None:
            return Occluders(np.concatenate([a.tris, b.tris]), np.concatenate([a.depth, b.depth]))
        return Occluders(np.concatenate([a.tris, b.tris]), np.concatenate([a.depth, b.depth]),
                         np.concatenate([a.vertices, b.vertices]),
                         np.concatenate([a.faces, b.faces + np.int32(len(a.vertices))]))


def sun_shadow(occluders: Occluders, depth: np.ndarray, K: np.ndarray, cam2_from_world: np.ndarray,
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
    scene = EmbreeScene()
    if occluders.faces is not None:
        TriangleMesh(scene, occluders.vertices, occluders.faces)
    else:
        TriangleMesh(scene, occluders.tris)
    origins = (points + T_NEAR * to_sun).astype(np.float32)
    dirs = np.broadcast_to(to_sun.astype(np.float32), origins.shape).copy()
    prim = scene.run(origins, dirs)
    small[need] = np.where(prim >= 0, occluders.depth[np.maximum(prim, 0)], 0.0)
    small = cv2.GaussianBlur(small, (0, 0), SOFTEN)
    return cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR) * (depth > 0)
