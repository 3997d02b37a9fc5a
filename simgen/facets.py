"""Triangles and their unit normals from parts, numpy only: what the renderer shades and the
texture layout maps (simgen.texture_layout), with the same bits for both."""

from __future__ import annotations

import numpy as np

from .world import Part


def shared(parts: list[Part]) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) vertices and (F, 3) faces of all parts in part order, the faces indexing the joint
    vertices (numpy, no trimesh caches)."""
    vs = [np.asarray(p.mesh.vertices).view(np.ndarray) for p in parts]
    fs = [np.asarray(p.mesh.faces).view(np.ndarray) for p in parts]
    return np.concatenate(vs), joint_faces(fs, [len(v) for v in vs])


def joint_faces(faces: list[np.ndarray], n_vertices: list[int]) -> np.ndarray:
    """Faces of several meshes indexing their concatenated vertices."""
    first = np.cumsum([0, *n_vertices[:-1]])
    return np.concatenate(faces) + np.repeat(first, [len(f) for f in faces])[:, None]


def triangles(parts: list[Part]) -> tuple[np.ndarray, np.ndarray]:
    """(F, 3, 3) triangles and (F, 3) unit normals of all parts."""
    return faceted(*shared(parts))


def faceted(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, 3, 3) triangles and (F, 3) unit normals of a mesh."""
    tris = np.take(vertices, faces, axis=0)  # vertices[faces], gathered faster
    return tris, normals(tris)


def lengths(v: np.ndarray) -> np.ndarray:
    """Euclidean lengths of (..., 3) vectors: np.linalg.norm's sum of squares in its order (the
    same bits), component by component, which numpy runs faster than a reduction over a short axis."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.sqrt(x * x + y * y + z * z)


def cross(a, b) -> np.ndarray:
    """np.cross of two 3-vectors: its products and differences in its order (the same bits), in
    plain floats, as np.cross's set-up costs some 30 times its arithmetic."""
    (a0, a1, a2), (b0, b1, b2) = np.asarray(a, dtype=float).tolist(), np.asarray(b, dtype=float).tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def normals(tris: np.ndarray) -> np.ndarray:
    """(F, 3) unit normals of (F, 3, 3) triangles. The edges and np.cross's products and
    differences, in its order (the same bits), one coordinate at a time: numpy's loops then run
    over all faces, not three numbers."""
    a0, a1, a2 = (tris[:, 1, j] - tris[:, 0, j] for j in range(3))
    b0, b1, b2 = (tris[:, 2, j] - tris[:, 0, j] for j in range(3))
    n = np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)
    n /= np.maximum(lengths(n), 1e-300)[:, None]
    return n


def beyond(vertices: np.ndarray, faces: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """(F,) bool: which faces lie wholly outside one of the half-spaces `planes` (P, 4), a point
    p being outside plane k where planes[k] @ (p, 1) < 0: a face whose three corners share such a
    plane cannot meet anything inside them all (a convex set). Each vertex's planes are found
    once, as bits (at most 8 planes), on the shared vertices (a fifth of the corners)."""
    if len(planes) > 8:
        raise ValueError(f"beyond: at most 8 planes, got {len(planes)}")
    d = vertices @ planes[:, :3].T + planes[:, 3]
    out = np.zeros(len(vertices), np.uint8)
    for k in range(len(planes)):
        out |= (d[:, k] < 0).view(np.uint8) << k
    a, b, c = np.take(out, faces, axis=0).T
    return (a & b & c) != 0
