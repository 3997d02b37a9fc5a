"""The façades' windows as the LiDAR meets them: the windows the camera's façade tiles show
(simgen.textures.Window), where the frame's texture layout puts them (simgen.texture_layout).

A beam that meets a wall inside a window's glass goes through the glazing and ends behind it
(kernels.window_returns): on a curtain just behind the glass, or in the room, a box one window
bay wide and one storey's clear height tall. Laser scans of façades show windows as holes with
scattered points behind them (what window extraction from terrestrial scans relies on, e.g. Pu
and Vosselman 2007): the echo from inside loses the glazing's two-way transmittance (much more
at grazing incidence) and is read as clutter, so oblique windows drop at ranges where the wall
around them still returns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import facets, textures
from ..texture_layout import FACADE_KINDS, static_layout, wall_frames
from ..world import World

# A room's depth behind its window: residential rooms run 4-6 m deep from the façade (no survey).
ROOM_DEPTH_M = 5.0
# A curtain hangs about 0.15 m inside the glass (on a rail at the inner face of the window reveal).
CURTAIN_GAP_M = 0.15


@dataclass(frozen=True)
class Windows:
    """Per static triangle, its row of `walls` (-1: no window can be on it); per row, its wall's
    frame: tx, ty (the unit tangent u grows along), s0, per_s (tile units of u per metre along),
    the tile's u shift, the wall's foot z, metres per tile in v, and its pane set; per pane set,
    its windows' rows: the glass's u0, u1, v0, v1, the mullion's u0, u1, curtain (0 or 1), the
    room's u0, u1, floor v and ceiling v, in tile units."""

    tri_wall: np.ndarray  # (F,) int32
    walls: np.ndarray  # (W, 8) float64
    panes: np.ndarray  # (S, P, 11) float64
    n_panes: np.ndarray  # (S,) int64

    @property
    def n_walls(self) -> int:
        return len(self.walls)

    @classmethod
    def none(cls, n_triangles: int) -> Windows:
        """No window on any of `n_triangles`."""
        return cls(np.full(n_triangles, -1, np.int32), np.zeros((0, 8)), np.zeros((0, 0, 11)),
                   np.zeros(0, np.int64))


def windows_of(world: World, n_triangles: int) -> Windows:
    """The window table of `world`'s static parts, which come first among the `n_triangles` of
    the LiDAR's target, in the same order (simgen.lidar.target)."""
    parts = list(world.static)
    if not parts:
        return Windows.none(n_triangles)
    tris, normals = facets.triangles(parts)
    first = np.cumsum([0] + [len(p.mesh.faces) for p in parts])
    sets: dict = {}
    rows, faces = [], []
    for w in static_layout(world, parts, normals).wearing:
        if w.kind not in FACADE_KINDS:
            continue
        own = first[w.part] + np.flatnonzero(w.faces)
        f = wall_frames(tris[own], normals[own])
        per_s = f.bays[:, 0] * textures.BAY_M / (np.maximum(f.width[:, 0], 1e-9) * w.tile[0])
        k = sets.setdefault((w.kind, w.variant), len(sets))
        rows.append(np.column_stack([f.along, f.s0[:, 0], per_s, np.full(len(own), w.shift), f.foot,
                                     np.full(len(own), w.tile[1]), np.full(len(own), k)]))
        faces.append(own)
    if not rows:
        return Windows.none(n_triangles)
    own = np.concatenate(faces)
    tri_wall = np.full(n_triangles, -1, np.int32)
    tri_wall[own] = np.arange(len(own))
    made = [textures.windows(kind, variant) for kind, variant in sets]
    panes = np.full((len(made), max(len(m) for m in made), 11), np.nan)
    for k, m in enumerate(made):
        for j, win in enumerate(m):
            panes[k, j] = [*win.glass, *win.mullion, float(win.curtain), *win.room]
    return Windows(tri_wall, np.concatenate(rows), panes, np.array([len(m) for m in made], np.int64))
