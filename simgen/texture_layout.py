"""Which texture tile each face of the static world wears, at what scale and offset: the frame's
appearance draws, made here once for the renderer (which draws the tiles) and the LiDAR (which
reads where the façade tiles have windows, simgen.lidar.windows). The textures are the
surfaces' materials at a finer scale than the meshes: a beam that meets a window meets glass.

The draws are the world's, not the look's: the same windows stand in every look (night,
thermal, untextured), though only the lit, textured look shows them to the camera.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import textures
from .factors import factor_rng
from .world import Part, World

FACADE_KINDS = ("brick", "plaster")  # the tiles with windows (textures._windows)
# Faces this close in direction (unit vector) and offset (m) share a wall.
_WALL_DIRECTION, _WALL_OFFSET = 1e-4, 0.01


@dataclass(frozen=True)
class Wearing:
    """Faces of one static part that wear one texture tile."""

    part: int  # index into the static parts
    faces: np.ndarray  # (F_part,) bool over the part's faces
    kind: str  # textures.TILE_M's key
    variant: int
    tile: tuple[float, float]  # metres per tile (u, v) on the surface
    shift: float | np.ndarray  # façades: a u offset (tiles); others: (2,) offsets in u and v


@dataclass(frozen=True)
class StaticLayout:
    gain: np.ndarray  # (P, 3) per-part colour gain (the look's colour jitter)
    wearing: list[Wearing]  # in draw order; faces in none of them are plain


def static_layout(world: World, parts: list[Part], normals: np.ndarray) -> StaticLayout:
    """The appearance draws of the static parts (`normals`: their faces' unit normals in part
    order, simgen.facets): one colour gain per part, then per textured part its tiles."""
    rng = factor_rng(world.seed, world.frame_index, "appearance")
    gain = np.exp(rng.normal(0.0, world.appearance.colour_jitter, (len(parts), 3)))
    ends = np.cumsum([len(p.mesh.faces) for p in parts])
    wearing = []
    for i, part in enumerate(parts):
        name = part.material.name
        n_faces = len(part.mesh.faces)
        if name == "facade":
            vertical = np.abs(normals[ends[i] - n_faces:ends[i], 2]) < 0.7
            wall = "brick" if rng.uniform() < 0.4 else "plaster"
            groups = [(vertical, wall), (~vertical, "roof")]
        elif name in textures.OF_MATERIAL:
            groups = [(np.ones(n_faces, bool), textures.OF_MATERIAL[name])]
        else:
            continue
        for sel, kind in groups:
            if not sel.any():
                continue
            variant = int(rng.integers(textures.VARIANTS))
            tile = tuple(np.asarray(textures.TILE_M[kind]) * rng.uniform(0.85, 1.15))
            shift = 0.5 * rng.integers(2) if kind in FACADE_KINDS else rng.uniform(0, 1, 2)
            wearing.append(Wearing(i, sel, kind, variant, tile, shift))
    return StaticLayout(gain, wearing)


@dataclass(frozen=True)
class WallFrames:
    """Per face of vertical walls, its wall's frame: a whole number of window bays across each
    wall, storeys counted from the wall's lowest point. A wall is every face in one vertical plane
    (the same horizontal normal and offset): a draped wall (simgen.relief) is split along its
    length and its foot follows the road, so per-triangle extents would cut the windows apart."""

    along: np.ndarray  # (F, 2) unit horizontal tangent t: u grows with t . (x, y)
    s: np.ndarray  # (F, 3) t . (x, y) of each corner
    s0: np.ndarray  # (F, 1) the wall's least t . (x, y)
    width: np.ndarray  # (F, 1) the wall's extent along t
    bays: np.ndarray  # (F, 1) whole window bays across it
    foot: np.ndarray  # (F,) the wall's lowest z


def wall_frames(tris: np.ndarray, normals: np.ndarray) -> WallFrames:
    t = np.c_[-normals[:, 1], normals[:, 0]]
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-9)
    s = np.einsum("fkj,fj->fk", tris[..., :2], t)
    offset = np.einsum("fj,fj->f", tris[:, 0, :2], np.c_[t[:, 1], -t[:, 0]])
    key = np.c_[np.round(t / _WALL_DIRECTION), np.round(offset / _WALL_OFFSET)] + 0.0  # no -0.0
    wall = np.unique(key, axis=0, return_inverse=True)[1].ravel()
    lo, hi, foot = (np.full(wall.max() + 1, x) for x in (np.inf, -np.inf, np.inf))
    np.minimum.at(lo, wall, s.min(axis=1))
    np.maximum.at(hi, wall, s.max(axis=1))
    np.minimum.at(foot, wall, tris[..., 2].min(axis=1))
    s0, width = lo[wall][:, None], (hi - lo)[wall][:, None]
    bays = np.maximum(1.0, np.round(width / textures.BAY_M))
    return WallFrames(t, s, s0, width, bays, foot[wall])


def facade_uv(tris: np.ndarray, normals: np.ndarray, tile: tuple[float, float],
              shift: float) -> np.ndarray:
    """(F, 3, 2) texture coordinates of vertical walls' faces (WallFrames)."""
    w = wall_frames(tris, normals)
    u = (w.s - w.s0) / np.maximum(w.width, 1e-9) * w.bays * textures.BAY_M / tile[0] + shift
    v = (tris[..., 2] - w.foot[:, None]) / tile[1]
    return np.stack([u, v], axis=2)
