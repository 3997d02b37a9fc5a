"""Static scenery: road surface, lane markings, curbs, sidewalks, verges, buildings, trees, poles,
fences. A pure function of its parameters (kept in `World.scenery` and in meta/), merged into one
part per material so the renderer and the LiDAR see few large meshes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
import trimesh

from .road import RoadLayout
from .world import Material, Part

ASPHALT = Material("asphalt", (0.09, 0.09, 0.10), 0.10)
MARKING = Material("marking", (0.85, 0.85, 0.82), 0.60)
CONCRETE = Material("curb", (0.45, 0.45, 0.43), 0.35)
SIDEWALK = Material("sidewalk", (0.32, 0.31, 0.30), 0.30)
VERGE = Material("verge", (0.14, 0.20, 0.08), 0.40)  # grass
FOREST_FLOOR = Material("forest_floor", (0.09, 0.07, 0.04), 0.30)
SAND = Material("sand", (0.62, 0.52, 0.36), 0.50)
BARK = Material("bark", (0.12, 0.08, 0.05), 0.20)
FOLIAGE = Material("foliage", (0.08, 0.20, 0.06), 0.45)
METAL = Material("pole", (0.30, 0.31, 0.33), 0.40)
FENCE = Material("fence", (0.35, 0.30, 0.25), 0.30)
_FACADES = [(0.55, 0.50, 0.42), (0.40, 0.30, 0.25), (0.60, 0.58, 0.55), (0.35, 0.36, 0.40),
            (0.65, 0.55, 0.40), (0.30, 0.25, 0.22)]
# 003's scene types: the ground beside the road, whether buildings may stand, the tree density
# multiplier along the sidewalk and the density of woods (trees per 100 m in a 25 m deep band).
ENVIRONMENTS = {"city": (VERGE, True, 1.0, 0.0), "grass": (VERGE, False, 0.5, 0.0),
                "forest": (FOREST_FLOOR, False, 1.0, 40.0), "desert": (SAND, False, 0.0, 0.0)}
MARK_Z = 0.01  # markings sit 1 cm above the asphalt so no renderer z-fights them
VERGE_WIDTH = 60.0


@dataclass
class Obstacle:
    """A static footprint actors must not overlap; `base` is the lowest height it occupies."""

    polygon: shapely.Polygon
    base: float = 0.0


def _strip(road: RoadLayout, s: np.ndarray, d0: float, d1: float, z0: float, z1: float | None = None):
    """A quad strip between lateral offsets d0 < d1 along s; horizontal at z0, or vertical
    from z0 to z1 (d0 == d1). Faces wound to face up (horizontal) or towards +d (vertical)."""
    n = len(s)
    if z1 is None:
        a = np.c_[road.xy(s, d0), np.full(n, z0)]
        b = np.c_[road.xy(s, d1), np.full(n, z0)]
    else:
        a = np.c_[road.xy(s, d0), np.full(n, z1)]
        b = np.c_[road.xy(s, d0), np.full(n, z0)]
    v = np.concatenate([a, b])
    i = np.arange(n - 1)
    faces = np.concatenate([np.c_[i, i + 1, i + n], np.c_[i + 1, i + n + 1, i + n]])
    return trimesh.Trimesh(v, faces, process=False)


def _flip(m: trimesh.Trimesh) -> trimesh.Trimesh:
    return trimesh.Trimesh(m.vertices, m.faces[:, ::-1], process=False)


def _oriented_box(road: RoadLayout, s: float, d: float, z: float, l: float, w: float, h: float):
    m = trimesh.creation.box(extents=[l, w, h])
    m.apply_translation([0, 0, h / 2])
    m.apply_transform(road.pose(s, d, z))
    return m


def _footprint(m: trimesh.Trimesh) -> shapely.Polygon:
    return shapely.convex_hull(shapely.MultiPoint(m.vertices[:, :2]))


def _rect(x0: float, x1: float, y0: float, y1: float, z: float) -> trimesh.Trimesh:
    """An upward-facing horizontal rectangle in world coordinates."""
    v = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)
    return trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)


def _wall(x: float, y0: float, y1: float, z0: float, z1: float, facing: float) -> trimesh.Trimesh:
    """A vertical rectangle in the plane world x = const, facing +x (facing > 0) or -x."""
    v = np.array([[x, y0, z0], [x, y1, z0], [x, y1, z1], [x, y0, z1]], float)
    faces = [[0, 1, 2], [0, 2, 3]] if facing > 0 else [[0, 2, 1], [0, 3, 2]]
    return trimesh.Trimesh(v, faces, process=False)


def _spans(road: RoadLayout, margin: float) -> list[tuple[float, float]]:
    """[s_min, s_max] minus the cross street widened by `margin` on both sides."""
    if road.cross_s is None:
        return [(road.s_min, road.s_max)]
    a, b = road.cross_s - road.cross_half_width - margin, road.cross_s + road.cross_half_width + margin
    return [(lo, hi) for lo, hi in ((road.s_min, a), (b, road.s_max)) if hi > lo]


def _cross_street(road: RoadLayout, add) -> shapely.Polygon:
    """Asphalt, curbs, sidewalks and markings of the cross street; returns the band to keep free
    of buildings, trees and poles."""
    cx, hw, sw, ch = road.cross_s, road.cross_half_width, road.sidewalk_width, road.curb_height
    far = VERGE_WIDTH + sw
    for y0, y1, walk in ((road.right_curb - far, road.right_curb, road.right_curb - sw),
                         (road.left_curb, road.left_curb + far, road.left_curb + sw)):
        add(ASPHALT, _rect(cx - hw, cx + hw, y0, y1, 0.0))
        w0, w1 = (y0, walk) if y1 == road.right_curb else (walk, y1)
        add(SIDEWALK, _rect(cx - hw - sw, cx - hw, w0, w1, ch))
        add(SIDEWALK, _rect(cx + hw, cx + hw + sw, w0, w1, ch))
        add(CONCRETE, _wall(cx - hw, y0, y1, 0.0, ch, +1))
        add(CONCRETE, _wall(cx + hw, y0, y1, 0.0, ch, -1))
        for off in (-0.12, 0.12):
            add(MARKING, _rect(cx + off - 0.075, cx + off + 0.075, y0, y1, MARK_Z))
    # Stop lines before the crossing, across the lanes of each direction.
    add(MARKING, _strip(road, np.array([cx - hw - 1.4, cx - hw - 1.0]), road.right_lane_edge,
                        road.divider, MARK_Z))
    add(MARKING, _strip(road, np.array([cx + hw + 1.0, cx + hw + 1.4]), road.divider,
                        road.left_lane_edge, MARK_Z))
    return shapely.box(cx - hw - sw - 1.0, -1e4, cx + hw + sw + 1.0, 1e4)


class _Meshes:
    """The scenery built so far: meshes by material, footprints, and the areas to keep clear."""

    def __init__(self, clear: list[shapely.Polygon]):
        self.by_mat: dict[Material, list[trimesh.Trimesh]] = {}
        self.obstacles: list[Obstacle] = []
        self.clear = clear

    def add(self, mat: Material, mesh: trimesh.Trimesh) -> None:
        self.by_mat.setdefault(mat, []).append(mesh)

    def blocks(self, mesh: trimesh.Trimesh) -> bool:
        """Whether the mesh would stand in a keep-clear area (a sight line, the cross street)."""
        fp = _footprint(mesh)
        return any(fp.intersects(c) for c in self.clear)


def _ground(road: RoadLayout, ground: Material, out: _Meshes) -> None:
    """Asphalt, the cross street, sidewalks, curb faces and the verges beyond them."""
    out.add(ASPHALT, _strip(road, road.samples(road.s_min, road.s_max), road.right_curb, road.left_curb, 0.0))
    if road.cross_s is not None:
        out.clear.append(_cross_street(road, out.add))
    ch, sw = road.curb_height, road.sidewalk_width
    for side in (-1, 1):
        curb = road.right_curb if side < 0 else road.left_curb
        outer = curb + side * sw
        lo, hi = sorted((curb, outer))
        for s0, s1 in _spans(road, 0.0):
            ss = road.samples(s0, s1)
            out.add(SIDEWALK, _strip(road, ss, lo, hi, ch))
            face = _strip(road, ss, curb, curb, 0.0, ch)
            out.add(CONCRETE, face if side < 0 else _flip(face))
        vlo, vhi = sorted((outer, outer + side * VERGE_WIDTH))
        for s0, s1 in _spans(road, sw):
            out.add(ground, _strip(road, road.samples(s0, s1), vlo, vhi, ch))


def _markings(road: RoadLayout, out: _Meshes) -> None:
    """Solid edge lines and divider, dashed lines between lanes of one direction."""
    w = 0.15
    spans = _spans(road, 0.0)
    for s0, s1 in spans:
        ss = road.samples(s0, s1)
        for d in (road.right_lane_edge + 0.25, road.left_lane_edge - 0.25):
            out.add(MARKING, _strip(road, ss, d - w / 2, d + w / 2, MARK_Z))
        for off in (-0.12, 0.12):
            out.add(MARKING, _strip(road, ss, road.divider + off - w / 2, road.divider + off + w / 2, MARK_Z))
    dash, gap = 3.0, 9.0
    starts = np.arange(np.floor(road.s_min / (dash + gap)) * (dash + gap), road.s_max, dash + gap)
    for k in range(1, road.lanes):
        for base in (road.right_lane_edge, road.left_lane_edge):
            d = base + k * road.lane_width if base == road.right_lane_edge else base - k * road.lane_width
            for s0 in starts:
                for lo_s, hi_s in spans:
                    ss = road.samples(max(s0, lo_s), min(s0 + dash, hi_s), 1.0)
                    if ss[-1] > ss[0]:
                        out.add(MARKING, _strip(road, ss, d - w / 2, d + w / 2, MARK_Z))


def _buildings(road: RoadLayout, side: int, outer: float, setback: float, rng: np.random.Generator,
               out: _Meshes) -> None:
    """A row of boxes behind the sidewalk, gaps between some; one drawn but blocked is skipped."""
    sb = road.s_min - 10.0
    while sb < road.s_max + 10.0:
        length = rng.uniform(8.0, 30.0)
        depth, height = rng.uniform(8.0, 16.0), rng.uniform(5.0, 20.0)
        d = outer + side * (setback + depth / 2)
        m = _oriented_box(road, sb + length / 2, d, road.curb_height, length, depth, height)
        sb += length + rng.choice([0.0, rng.uniform(2.0, 10.0)])
        if out.blocks(m):
            continue
        out.add(Material("facade", _FACADES[int(rng.integers(len(_FACADES)))], 0.35), m)
        out.obstacles.append(Obstacle(_footprint(m)))


def _fences(road: RoadLayout, side: int, outer: float, out: _Meshes) -> None:
    """A 1.2 m fence along the sidewalk's outer edge, broken by the cross street."""
    ch = road.curb_height
    for s0, s1 in _spans(road, road.sidewalk_width):
        m = _strip(road, road.samples(s0, s1), outer - side * 0.3, outer - side * 0.3, ch, ch + 1.2)
        out.add(FENCE, m if side < 0 else _flip(m))


def _trees(road: RoadLayout, side: int, outer: float, per_100m: float, woods: float,
           rng: np.random.Generator, out: _Meshes) -> None:
    """Trees on the sidewalk and, in woods, behind it; a crown in a keep-clear area drops the tree."""
    ch, sw = road.curb_height, road.sidewalk_width
    n_trees = rng.poisson(per_100m * (road.s_max - road.s_min) / 100.0)
    n_woods = rng.poisson(woods * (road.s_max - road.s_min) / 100.0)
    sidewalk_d = outer - side * min(1.0, sw / 2)
    spots = [(st, sidewalk_d) for st in np.sort(rng.uniform(road.s_min, road.s_max, n_trees))]
    spots += [(st, outer + side * rng.uniform(3.0, 28.0))
              for st in np.sort(rng.uniform(road.s_min, road.s_max, n_woods))]
    for st, d in spots:
        trunk_h, r = rng.uniform(2.0, 3.0), rng.uniform(1.0, 2.0)
        x, y = road.xy(st, d)
        trunk = trimesh.creation.cylinder(radius=0.15, height=trunk_h, sections=8)
        trunk.apply_translation([x, y, ch + trunk_h / 2])
        crown = trimesh.creation.icosphere(subdivisions=1, radius=r)
        crown.apply_translation([x, y, ch + trunk_h + 0.8 * r])
        if out.blocks(crown):
            continue
        out.add(BARK, trunk)
        out.add(FOLIAGE, crown)
        out.obstacles.append(Obstacle(_footprint(trunk).buffer(0.1)))
        out.obstacles.append(Obstacle(_footprint(crown), base=ch + trunk_h))


def _poles(road: RoadLayout, side: int, curb: float, spacing: float, rng: np.random.Generator,
           out: _Meshes) -> None:
    """7 m poles half a metre behind the curb, evenly spaced from a random start."""
    ch = road.curb_height
    for sp in np.arange(road.s_min + rng.uniform(0, spacing), road.s_max, spacing):
        x, y = road.xy(sp, curb + side * 0.5)
        pole = trimesh.creation.cylinder(radius=0.09, height=7.0, sections=8)
        pole.apply_translation([x, y, ch + 3.5])
        if out.blocks(pole):
            continue
        out.add(METAL, pole)
        out.obstacles.append(Obstacle(_footprint(pole).buffer(0.1)))


def build_scenery(params: dict) -> tuple[list[Part], list[Obstacle]]:
    """Static parts (world frame) and their footprints, from the scenery parameters.

    `params["keep_clear"]` (optional): a list of (x, y) polygon vertices where no building, tree
    or pole may stand, e.g. the line of sight of an orbit camera to its target.
    """
    road = RoadLayout(**params["road"])
    clutter = params["clutter"]
    ground, buildings, tree_factor, woods = ENVIRONMENTS[clutter.get("environment", "city")]
    rng = np.random.default_rng(params["seed"])
    out = _Meshes([shapely.Polygon(params["keep_clear"])] if params.get("keep_clear") else [])
    _ground(road, ground, out)
    _markings(road, out)
    # Buildings, trees, poles and fences along both sides: one side's draws, then the other's.
    for side in (-1, 1):
        curb = road.right_curb if side < 0 else road.left_curb
        outer = curb + side * road.sidewalk_width
        if clutter["buildings"] and buildings:
            _buildings(road, side, outer, clutter["building_setback"], rng, out)
        elif clutter["fences"]:  # where no buildings line the sidewalk
            _fences(road, side, outer, out)
        _trees(road, side, outer, tree_factor * clutter["trees_per_100m"], woods, rng, out)
        if clutter["pole_spacing"] > 0:
            _poles(road, side, curb, clutter["pole_spacing"], rng, out)
    parts = [Part(trimesh.util.concatenate(ms), mat) for mat, ms in out.by_mat.items()]
    return parts, out.obstacles
