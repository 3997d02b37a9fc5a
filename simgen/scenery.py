"""Static scenery: road surface, lane markings, curbs, sidewalks, verges, buildings, trees, poles,
fences, street furniture (signs, signals, bins, bollards, cycle stands). A pure function of its
parameters (kept in `World.scenery` and in meta/), merged into one part per material so the
renderer and the LiDAR see few large meshes. The pieces are mostly plain vertices and faces
(simgen.meshes.Shape): a trimesh for each of the hundreds a frame cost ~30 ms.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass

import numpy as np
import shapely
import trimesh

# The scenery's materials at 905 nm and their sources: simgen.materials.
from .materials import (ASPHALT, BARK, CONCRETE, FACADE_REFLECTIVITY, FENCE, FOLIAGE,  # noqa: F401
                        FOREST_FLOOR, MARKING, METAL, SAND, SHRUB_MASS, SIDEWALK, SIGN_BLUE, SIGN_RED,
                        SIGN_WHITE, SIGN_YELLOW, TRIM, VERGE, paint_material, signal_lens)
from .meshes import Shape, bicycle, box, extrude
from .relief import drape_parts
from .road import RoadLayout
from .world import Material, Part, fit_parts

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
        a = np.column_stack((road.xy(s, d0), np.full(n, z0)))
        b = np.column_stack((road.xy(s, d1), np.full(n, z0)))
    else:
        a = np.column_stack((road.xy(s, d0), np.full(n, z1)))
        b = np.column_stack((road.xy(s, d0), np.full(n, z0)))
    v = np.concatenate([a, b])
    i = np.arange(n - 1)
    faces = np.concatenate([np.column_stack((i, i + 1, i + n)), np.column_stack((i + 1, i + n + 1, i + n))])
    return Shape(v, faces)


def _flip(m: Shape) -> Shape:
    return Shape(m.vertices, m.faces[:, ::-1])


def _oriented_box(road: RoadLayout, s: float, d: float, z: float, l: float, w: float, h: float):
    m = trimesh.creation.box(extents=[l, w, h])
    m.apply_translation([0, 0, h / 2])
    m.apply_transform(road.pose(s, d, z))
    return m


def _footprint(m: Shape | trimesh.Trimesh) -> shapely.Polygon:
    return shapely.convex_hull(shapely.MultiPoint(m.vertices[:, :2]))


def _plain(m: trimesh.Trimesh) -> Shape:
    """A template mesh's arrays as plain numpy (arithmetic on trimesh's tracked arrays costs more)."""
    return Shape(np.asarray(m.vertices), np.asarray(m.faces))


_QUAD = np.array([[0, 1, 2], [0, 2, 3]])  # a quad's corners in order round it, as two triangles


def _rect(x0: float, x1: float, y0: float, y1: float, z: float) -> Shape:
    """An upward-facing horizontal rectangle in world coordinates."""
    v = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)
    return Shape(v, _QUAD)


def _wall(x: float, y0: float, y1: float, z0: float, z1: float, facing: float) -> Shape:
    """A vertical rectangle in the plane world x = const, facing +x (facing > 0) or -x."""
    v = np.array([[x, y0, z0], [x, y1, z0], [x, y1, z1], [x, y0, z1]], float)
    return Shape(v, _QUAD if facing > 0 else _QUAD[:, [0, 2, 1]])


def _spans(road: RoadLayout, margin: float) -> list[tuple[float, float]]:
    """[s_min, s_max] minus the cross street widened by `margin` on both sides."""
    if road.cross_s is None:
        return [(road.s_min, road.s_max)]
    a, b = road.cross_s - road.cross_half_width - margin, road.cross_s + road.cross_half_width + margin
    return [(lo, hi) for lo, hi in ((road.s_min, a), (b, road.s_max)) if hi > lo]


def _cross_street(road: RoadLayout, add, far: float | None = None) -> shapely.Polygon:
    """Asphalt, curbs, sidewalks and markings of the cross street out to `far` beyond each curb
    (default: the verge's far edge); returns the band to keep free of buildings, trees and poles."""
    cx, hw, sw, ch = road.cross_s, road.cross_half_width, road.sidewalk_width, road.curb_height
    far = VERGE_WIDTH + sw if far is None else far
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
        self.by_mat: dict[Material, list[Shape | trimesh.Trimesh]] = {}
        self.obstacles: list[Obstacle] = []
        self.clear = clear
        self.sight = list(clear)  # the caller's keep-clear areas: even the signals keep off them

    def add(self, mat: Material, mesh: Shape | trimesh.Trimesh) -> None:
        self.by_mat.setdefault(mat, []).append(mesh)

    def blocks(self, mesh: Shape | trimesh.Trimesh) -> bool:
        """Whether the mesh would stand in a keep-clear area (a sight line, the cross street)."""
        fp = _footprint(mesh)
        return any(fp.intersects(c) for c in self.clear)


def _carriageway(road: RoadLayout, out: _Meshes) -> None:
    """The asphalt from curb to curb; a crowned one in two strips that meet at the crown (the
    divider), so that the draped surface bends there and not across a triangle."""
    ss = road.samples(road.s_min, road.s_max)
    if road.crown == 0.0:
        out.add(ASPHALT, _strip(road, ss, road.right_curb, road.left_curb, 0.0))
        return
    out.add(ASPHALT, _strip(road, ss, road.right_curb, road.divider, 0.0))
    out.add(ASPHALT, _strip(road, ss, road.divider, road.left_curb, 0.0))


def _ground(road: RoadLayout, ground: Material, out: _Meshes) -> None:
    """Asphalt, the cross street, sidewalks, curb faces and the verges beyond them."""
    _carriageway(road, out)
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
        out.add(Material("facade", _FACADES[int(rng.integers(len(_FACADES)))], FACADE_REFLECTIVITY), m)
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


_POLE = _plain(trimesh.creation.cylinder(radius=0.09, height=7.0, sections=8))  # moved to each pole's place


def _poles(road: RoadLayout, side: int, curb: float, spacing: float, rng: np.random.Generator,
           out: _Meshes) -> None:
    """7 m poles half a metre behind the curb, evenly spaced from a random start."""
    ch = road.curb_height
    for sp in np.arange(road.s_min + rng.uniform(0, spacing), road.s_max, spacing):
        x, y = road.xy(sp, curb + side * 0.5)
        pole = _moved(_POLE, [x, y, ch + 3.5])
        if out.blocks(pole):
            continue
        out.add(METAL, pole)
        out.obstacles.append(Obstacle(_footprint(pole).buffer(0.1)))


# --- Frontage (clutter.frontage): lots of several kinds behind each sidewalk --------------------
# The first street model stands one row of buildings `building_setback` behind each sidewalk: a
# closed box to the LiDAR (urban range p90 19 m against 24.5 m in real KITTI, 0.9 % of returns
# beyond 40 m against 2.7 %). With `clutter.frontage` each side is a sequence of lots, cut by side
# streets. The figures are German rules, guidelines and plans (KITTI was recorded in Karlsruhe,
# Baden-Wuerttemberg); where no published figure was found the comment says so.
#
# A lot is part of one block side. Block sides of gridded cities are 60-200 m and blocks 60-100 m
# deep, measured between street centre lines (Portland 80 x 80 m, Houston 100 x 100, Sacramento
# 120 x 120, Calgary 100 x 170, Edmonton 60 x 171; Wikipedia "City block"); one block side often
# holds more than one use, so a lot is 30-120 m long. Side streets: `side_streets_per_100m`.
LOT_LENGTH = (30.0, 120.0)
BLOCK_DEPTH = (60.0, 100.0)  # centre line of this street to that of the next, parallel one
LAND_DEPTH = 100.0  # m of land behind each sidewalk: a block and a half (VERGE_WIDTH without frontage)
SIDE_STREET_GAP = 20.0  # m of frontage at least between two side streets, or one and the cross street
# Detached houses. LBO BW section 5: a building keeps 0.4 x its wall height, at least 2.5 m, from
# every plot boundary. Footprints of one- and two-family houses: 8-14 m a side (no survey found;
# 100-200 m2 of floor on two storeys). Height of the box, between eaves and ridge: 6-11 m (ridge
# limits of 11 m are typical, e.g. Lalendorf B-plan No. 5).
HOUSE_LENGTH = (8.0, 14.0)
HOUSE_DEPTH = (8.0, 12.0)
HOUSE_HEIGHT = (6.0, 11.0)
BOUNDARY_MIN, BOUNDARY_SHARE = 2.5, 0.4
PLOT_SLACK = (0.0, 6.0)  # m of plot frontage beyond the LBO minimum: no survey found
# Front yards: building lines 3-5 m behind the street line (Lalendorf B-plan No. 5), 6-7 m where
# carports stand in front of the house (hausbau-forum.de on B-plans).
FRONT_YARD = (3.0, 7.0)
# Front-yard boundaries along the sidewalk: hedges planted at 1.0-1.5 m and kept at most 1.8 m
# (Hamburg B-plans; Nachbarrecht, Sennestadt design guide), fences and walls at most 1.2 m
# (Sennestadt design guide). No survey of their shares was found: hedge, fence, wall and none
# equally often. A gap of 3 m (path or drive) in each plot's boundary.
HEDGE_HEIGHT, HEDGE_DEPTH = (1.0, 1.8), (0.6, 1.0)
FENCE_HEIGHT = (0.8, 1.2)
WALL_HEIGHT = (0.5, 1.2)
BOUNDARIES = ("hedge", "fence", "wall", "none")
DRIVE_GAP = 3.0
# Side and rear plot boundaries: hedge, fence or wall, equally often (no survey found); the rear
# one 5-15 m behind the house (gardens: no survey found). LBO BW section 37: one parking space
# per dwelling; LBO BW section 6: garages up to 3 m high may stand in the boundary distance.
# Garage or open stall equally often (no survey found); a prefabricated single garage is 3 x 6 m;
# GaVO: 5 m of apron before its door.
BACK_GARDEN = (5.0, 15.0)
GARAGE, GARAGE_HEIGHT, GARAGE_APRON = (3.0, 6.0), (2.5, 3.0), 5.0
# Planting (Hamburg B-plans' requirements): at least one small-crowned tree per 150 m2 of unbuilt
# plot area, taken as the mean for gardens; one tree and three shrubs per 50 m2 of front yard,
# one plan's requirement where other front yards are lawn or paved: a lot gets a share U(0, 1).
YARD_M2_PER_TREE, YARD_SHRUBS_PER_TREE, GARDEN_M2_PER_TREE = 50.0, 3.0, 150.0
SHRUB_RADIUS = (0.5, 1.2)
# Open land: a mown lawn or a meadow, equally often (no survey found). Urban meadows are mown
# once or twice a year, the last cut from September on (Berlin Strassen- und Gruenflaechenamt;
# Bayerischer Rundfunk garden guide: end of September / October), so on KITTI's drives (26
# September - 3 October 2011) they stood near full height: 0.3-1.0 m. Park trees: at least one
# large-crowned tree per 300 m2 of unbuilt land (Hamburg B-plans' requirement), taken as the mean.
MEADOW_HEIGHT = (0.3, 1.0)
PARK_M2_PER_TREE = 300.0
# Trees (GALK street tree list: the common street trees grow 8-20 m tall with crowns 4-12 m
# wide; small-crowned garden trees 4-10 m tall, 3-6 m wide). Clearance under crowns: 2.5 m over
# footways, 4.5 m over the carriageway (Lichtraumprofil, RASt 06).
TREE_HEIGHT, CROWN_RADIUS = (8.0, 18.0), (2.0, 5.0)
SMALL_TREE_HEIGHT, SMALL_CROWN_RADIUS = (4.0, 10.0), (1.5, 3.0)
CLEAR_FOOTWAY, CLEAR_ROAD = 2.5, 4.5
# Garden trees branch lower: nursery grades of fruit and garden trees have clear stems of 1.0-1.6 m
# (half-standard) to 1.8-2.0 m (standard).
GARDEN_CROWN_BASE = (1.0, 2.0)
# Belts of trees and shrubs along the street (German "Gehoelzstreifen", "Strassenbegleitgruen"):
# a grass margin behind the sidewalk, then a closed mass of shrubs 2-5 m tall with small trees
# standing in it, 3-10 m deep, branched to the ground (hedgerows and roadside plantings are not
# pruned from 1 March to 30 September, BNatSchG section 39(5), so on KITTI's drives they stood
# in full leaf and growth). The sizes are typical of such plantings, not a survey. The LiDAR
# sees the shrubs as one closed leaf mass (simgen.materials.SHRUB_MASS).
GREEN_MARGIN, GREEN_DEPTH = (0.5, 2.0), (3.0, 10.0)
SHRUB_BELT_RADIUS, SHRUB_BELT_HEIGHT = (1.0, 2.5), (2.0, 5.0)
GREEN_M2_PER_TREE = 60.0  # one small tree among the shrubs per 60 m2 of belt: a judgement
# Car parks (EAR 05): perpendicular stalls 2.50 x 5.00 m, aisles 6.00 m; a module is two stall
# rows about an aisle, 1-2 modules deep, a 1.5 m planting strip before, between and after them
# with one small- to medium-crowned tree per 4-5 stalls (Hamburg and Reinbek B-plans); a store
# behind, one storey of 5-8 m (no survey found).
STALL_W, STALL_L, AISLE, PLANTING = 2.5, 5.0, 6.0, 1.5
STALLS_PER_TREE = 4.5
STORE_HEIGHT, STORE_DEPTH = (5.0, 8.0), (20.0, 40.0)
# Closed rows keep the first street model's buildings: 8-30 m long, 8-16 m deep, 5-20 m high.
ROW_LENGTH, ROW_DEPTH, ROW_HEIGHT = (8.0, 30.0), (8.0, 16.0), (5.0, 20.0)


@dataclass(frozen=True)
class Lot:
    """One stretch [s0, s1] of one side (-1 right, +1 left) given to one kind of lot; a car
    park's paved depth behind the sidewalk in `depth`."""

    side: int
    s0: float
    s1: float
    kind: str
    depth: float = 0.0


@dataclass
class Frontage:
    """The plan of the lots, side streets and car-park stalls: what sample.py needs to place
    actors, and what build_scenery meshes. A pure function of the scenery parameters."""

    lots: list[Lot]
    mouths: dict[int, list[tuple[float, float]]]  # per side: side streets' carriageways [s0, s1]
    stalls: list[np.ndarray]  # (4, 4) world poses, stall centre on the paving, x away from the road

    def in_mouth(self, side: int, s: float, margin: float = 0.0) -> bool:
        """Whether arc length s lies on a side street's carriageway on that side (widened)."""
        return any(a - margin <= s <= b + margin for a, b in self.mouths[side])


def _outer(road: RoadLayout, side: int) -> float:
    return (road.right_curb if side < 0 else road.left_curb) + side * road.sidewalk_width


def _cut(spans: list[tuple[float, float]], a: float, b: float) -> list[tuple[float, float]]:
    out = []
    for lo, hi in spans:
        out += [(x, y) for x, y in ((lo, min(hi, a)), (max(lo, b), hi)) if y > x]
    return out


def plan_frontage(params: dict) -> Frontage | None:
    """The lots of both sides, or None when the spec keeps the first street model."""
    clutter = params["clutter"]
    mix = {k: float(w) for k, w in sorted((clutter.get("frontage") or {}).items()) if w > 0}
    if not (mix and clutter["buildings"] and ENVIRONMENTS[clutter.get("environment", "city")][1]):
        return None
    road = RoadLayout(**params["road"])
    rng = np.random.default_rng([int(params["seed"]), 1])
    kinds, p = list(mix), np.array(list(mix.values()))
    lo, hi = road.s_min - 10.0, road.s_max + 10.0
    sw, street = road.sidewalk_width, 2.0 * road.lane_width  # side streets: a lane each way
    lots, mouths, stalls = [], {-1: [], 1: []}, []
    for side in (-1, 1):
        taken = [] if road.cross_s is None else [(road.cross_s - road.cross_half_width - sw,
                                                  road.cross_s + road.cross_half_width + sw)]
        rate = float(clutter.get("side_streets_per_100m", 0.0))
        for s in np.sort(rng.uniform(road.s_min + 10.0, road.s_max - 10.0,
                                     rng.poisson(rate * (road.s_max - road.s_min) / 100.0))):
            a, b = s - street / 2, s + street / 2
            if all(b + sw + SIDE_STREET_GAP < t0 or a - sw - SIDE_STREET_GAP > t1 for t0, t1 in taken):
                mouths[side].append((float(a), float(b)))
                taken.append((a - sw, b + sw))
        spans = [(lo, hi)]
        for a, b in taken:
            spans = _cut(spans, a, b)
        for s0, s1 in spans:
            s = s0
            while s < s1:
                end = min(s + rng.uniform(*LOT_LENGTH), s1)
                if s1 - end < LOT_LENGTH[0] / 2:
                    end = s1
                kind = kinds[int(rng.choice(len(kinds), p=p / p.sum()))]
                lot = Lot(side, float(s), float(end), kind)
                if kind == "car_park":
                    lot, lot_stalls = _car_park_plan(road, lot, rng)
                    stalls += lot_stalls
                lots.append(lot)
                s = end
    return Frontage(lots, mouths, stalls)


def _car_park_plan(road: RoadLayout, lot: Lot, rng: np.random.Generator) -> tuple[Lot, list[np.ndarray]]:
    """1-2 modules of two stall rows about an aisle; the stalls' poses (x away from the road)."""
    side, outer, k = lot.side, _outer(road, lot.side), road.curvature
    modules = int(rng.integers(1, 3))
    module = 2 * STALL_L + AISLE
    stalls = []
    for m in range(modules):
        q0 = PLANTING + m * (module + PLANTING)
        for q in (q0 + STALL_L / 2, q0 + STALL_L + AISLE + STALL_L / 2):
            d = outer + side * q
            pitch = STALL_W / (1.0 - k * d)  # arc length at offset d is (1 - k d) ds
            for s in np.arange(lot.s0 + 3.0 + pitch / 2, lot.s1 - 3.0 - pitch / 2, pitch):
                stalls.append(road.pose(float(s), d, road.curb_height, side * np.pi / 2))
    depth = PLANTING + modules * (module + PLANTING)
    return Lot(lot.side, lot.s0, lot.s1, lot.kind, depth), stalls


# Unit meshes the frontage scales and places by plain vertex arithmetic (thousands per world:
# trimesh's creation and transform calls cost ~20x more).
_UNIT_BOX = _plain(trimesh.creation.box(extents=[1.0, 1.0, 1.0]))
_UNIT_CYLINDER = _plain(trimesh.creation.cylinder(radius=1.0, height=1.0, sections=8))
_UNIT_SPHERES = {k: _plain(trimesh.creation.icosphere(subdivisions=k, radius=1.0)) for k in (0, 1)}
_SPHERE_TOP = float(_UNIT_SPHERES[0].vertices[:, 2].max())  # the coarse sphere's reach up (and down)


def _placed(unit: Shape, scale, at) -> Shape:
    return Shape(unit.vertices * np.asarray(scale) + np.asarray(at), unit.faces)


def _moved(m: Shape, at) -> Shape:
    """m moved by `at` as trimesh's apply_translation moves it (the same homogeneous product, so
    the same bits)."""
    move = np.eye(4)
    move[:3, 3] = at
    return Shape(trimesh.transformations.transform_points(m.vertices, move), m.faces)


def _qbox(road: RoadLayout, side: int, s0: float, s1: float, q0: float, q1: float, z: float,
          h: float) -> Shape:
    """A box over [s0, s1] along the road and q0..q1 metres behind the sidewalk of `side`, its
    long axes along the road's heading at the box's centre."""
    s, d = (s0 + s1) / 2, _outer(road, side) + side * (q0 + q1) / 2
    psi = float(road.heading(s))
    c, sn = np.cos(psi), np.sin(psi)
    local = _UNIT_BOX.vertices * [s1 - s0, q1 - q0, h]
    x, y = road.xy(s, d)
    v = np.column_stack((x + c * local[:, 0] - sn * local[:, 1], y + sn * local[:, 0] + c * local[:, 1],
                         local[:, 2] + z + h / 2))
    return Shape(v, _UNIT_BOX.faces)


def _quad_polygon(road: RoadLayout, s0: float, s1: float, d0: float, d1: float) -> shapely.Polygon:
    ss = road.samples(s0, s1)
    return shapely.Polygon(np.concatenate([road.xy(ss, d0), road.xy(ss[::-1], d1)]))


def _add_building(out: _Meshes, rng: np.random.Generator, m: Shape) -> None:
    if out.blocks(m):
        return
    out.add(Material("facade", _FACADES[int(rng.integers(len(_FACADES)))], FACADE_REFLECTIVITY), m)
    out.obstacles.append(Obstacle(_footprint(m)))


def _tree(out: _Meshes, x: float, y: float, z: float, height: float, r: float, base: float,
          trunk_r: float = 0.2) -> None:
    """Trunk up to `base` above z, an ellipsoid crown of radius r from base to height."""
    rz = max(0.5, (height - base) / 2)
    at = shapely.Point(x, y)
    crown_fp = at.buffer(r, 8)
    if out.clear and any(crown_fp.intersects(c) for c in out.clear):
        return
    out.add(BARK, _placed(_UNIT_CYLINDER, [trunk_r, trunk_r, base + rz], [x, y, z + (base + rz) / 2]))
    out.add(FOLIAGE, _placed(_UNIT_SPHERES[1], [r, r, rz], [x, y, z + base + rz]))
    out.obstacles.append(Obstacle(at.buffer(trunk_r + 0.1, 4)))
    out.obstacles.append(Obstacle(crown_fp, base=z + base))


def _shrub(out: _Meshes, x: float, y: float, z: float, r: float) -> None:
    _ellipsoid(out, FOLIAGE, x, y, r, 0.7 * r, z + 0.7 * r)


def _ellipsoid(out: _Meshes, mat: Material, x: float, y: float, r: float, rz: float, cz: float) -> None:
    """A coarse ellipsoid of radius r across and rz up about (x, y, cz), its footprint an obstacle;
    left out where it would reach into a keep-clear area."""
    fp = shapely.Point(x, y).buffer(r, 4)
    if not (out.clear and any(fp.intersects(c) for c in out.clear)):
        out.add(mat, _placed(_UNIT_SPHERES[0], [r, r, rz], [x, y, cz]))
        out.obstacles.append(Obstacle(fp))


def _small_trees(road: RoadLayout, side: int, s0: float, s1: float, q0: float, q1: float,
                 n: int, rng: np.random.Generator, out: _Meshes, base: tuple[float, float]) -> None:
    """n small-crowned trees over [s0, s1] x [q0, q1] behind the sidewalk, crowns from `base`."""
    outer, ch = _outer(road, side), road.curb_height
    for _ in range(n):
        h, r = rng.uniform(*SMALL_TREE_HEIGHT), rng.uniform(*SMALL_CROWN_RADIUS)
        x, y = road.xy(rng.uniform(s0, s1), outer + side * rng.uniform(q0, q1))
        _tree(out, x, y, ch, h, r, rng.uniform(*base), 0.12)


def _boundary(road: RoadLayout, side: int, s0: float, s1: float, kind: str,
              rng: np.random.Generator, out: _Meshes) -> None:
    """A front boundary along the back of the sidewalk over [s0, s1], in pieces of at most 10 m
    (boxes follow a curved road); nothing when kind is none."""
    if kind == "none" or s1 - s0 < 0.5:
        return
    h, t, mat = _boundary_style(kind, rng)
    for a, b in _pieces(s0, s1):
        _add_solid(out, mat, _qbox(road, side, a, b, 0.2, 0.2 + t, road.curb_height, h))


def _pieces(s0: float, s1: float, longest: float = 10.0) -> list[tuple[float, float]]:
    """[s0, s1] cut into equal pieces of at most `longest` metres (boxes follow a curved road)."""
    cuts = np.linspace(s0, s1, int(np.ceil((s1 - s0) / longest)) + 1)
    return list(itertools.pairwise(cuts.tolist()))


def _boundary_style(kind: str, rng: np.random.Generator) -> tuple[float, float, Material]:
    """Height, thickness and material of a hedge, fence or wall."""
    if kind == "hedge":
        return rng.uniform(*HEDGE_HEIGHT), rng.uniform(*HEDGE_DEPTH), FOLIAGE
    if kind == "fence":
        return rng.uniform(*FENCE_HEIGHT), 0.05, FENCE
    return rng.uniform(*WALL_HEIGHT), 0.25, CONCRETE


def _add_solid(out: _Meshes, mat: Material, m: Shape) -> None:
    if not out.blocks(m):
        out.add(mat, m)
        out.obstacles.append(Obstacle(_footprint(m)))


def _house_row(road: RoadLayout, side: int, s0: float, s1: float, q: float,
               rng: np.random.Generator, out: _Meshes, yard: bool) -> float:
    """Detached houses whose fronts stand q metres behind the sidewalk over [s0, s1], each on its
    plot with the LBO's boundary distances; with `yard`, the front boundary and planting.
    Returns the deepest house's depth."""
    ch, deepest = road.curb_height, 0.0
    s = s0
    while True:
        length, depth, height = (rng.uniform(*HOUSE_LENGTH), rng.uniform(*HOUSE_DEPTH),
                                 rng.uniform(*HOUSE_HEIGHT))
        clear = max(BOUNDARY_MIN, BOUNDARY_SHARE * height)
        plot = length + 2 * clear + rng.uniform(*PLOT_SLACK)
        if s + plot > s1:
            break
        at = s + clear + rng.uniform(0.0, plot - length - 2 * clear)
        _add_building(out, rng, _qbox(road, side, at, at + length, q, q + depth, ch, height))
        deepest = max(deepest, depth)
        if yard:  # the drive in the wider side gap, a garage at its end or an open stall
            lo, hi = (s, at) if at - s > s + plot - at - length else (at + length, s + plot)
            gap = (lo + hi - DRIVE_GAP) / 2
            if rng.uniform() < 0.5 and hi - lo >= GARAGE[0] + 0.2:
                q0 = max(q, GARAGE_APRON)
                _add_building(out, rng, _qbox(road, side, gap, gap + GARAGE[0], q0, q0 + GARAGE[1], ch,
                                              rng.uniform(*GARAGE_HEIGHT)))
            kind = BOUNDARIES[int(rng.integers(len(BOUNDARIES)))]
            _boundary(road, side, s, gap, kind, rng, out)
            _boundary(road, side, gap + DRIVE_GAP, s + plot, kind, rng, out)
            # the side boundary (to the previous plot) and the rear one, behind the garden
            h, t, mat = _boundary_style(BOUNDARIES[int(rng.integers(len(BOUNDARIES) - 1))], rng)
            rear = q + depth + rng.uniform(*BACK_GARDEN)
            _add_solid(out, mat, _qbox(road, side, s, s + t, 1.2, rear, ch, h))
            for a, b in _pieces(s, s + plot):
                _add_solid(out, mat, _qbox(road, side, a, b, rear, rear + t, ch, h))
            lam = rng.uniform() * plot * q / YARD_M2_PER_TREE
            _small_trees(road, side, s + 1.0, s + plot - 1.0, 1.5, q - 1.0, rng.poisson(lam), rng, out,
                         (CLEAR_FOOTWAY, CLEAR_FOOTWAY))
            outer = _outer(road, side)
            for _ in range(rng.poisson(YARD_SHRUBS_PER_TREE * lam)):
                x, y = road.xy(rng.uniform(s + 0.5, s + plot - 0.5), outer + side * rng.uniform(1.5, q - 0.5))
                _shrub(out, x, y, ch, rng.uniform(*SHRUB_RADIUS))
        s += plot
    return deepest


def _closed_row(road: RoadLayout, side: int, s0: float, s1: float, q: float,
                rng: np.random.Generator, out: _Meshes) -> float:
    """The first street model's row of buildings over [s0, s1], fronts q behind the sidewalk."""
    ch, deepest, s = road.curb_height, 0.0, s0
    while s < s1 - ROW_LENGTH[0] / 2:
        length = min(rng.uniform(*ROW_LENGTH), s1 - s)
        depth, height = rng.uniform(*ROW_DEPTH), rng.uniform(*ROW_HEIGHT)
        _add_building(out, rng, _qbox(road, side, s, s + length, q, q + depth, ch, height))
        deepest = max(deepest, depth)
        s += length + rng.choice([0.0, rng.uniform(2.0, 10.0)])
    return deepest


def _across_block(road: RoadLayout, lot: Lot, near: float, rng: np.random.Generator,
                  out: _Meshes, gardens: bool = True) -> float:
    """The next street's buildings (their backs to us) across the block, `near` metres behind
    the sidewalk being the deepest building front here; with `gardens`, gardens with small
    trees in between. The next street is as wide as this one (centre line to the back of the
    sidewalk). Returns how far behind the sidewalk that row stands (LAND_DEPTH: none)."""
    yard2, depth2 = rng.uniform(*FRONT_YARD), rng.uniform(*HOUSE_DEPTH)
    half = abs(_outer(road, lot.side) - road.divider)
    q = max(near + 10.0, rng.uniform(*BLOCK_DEPTH) - 2 * half - yard2 - depth2)
    if q > LAND_DEPTH - HOUSE_DEPTH[0]:
        return LAND_DEPTH
    if rng.uniform() < 0.5:
        _house_row(road, lot.side, lot.s0, lot.s1, q, rng, out, yard=False)
    else:
        _closed_row(road, lot.side, lot.s0, lot.s1, q, rng, out)
    if gardens:
        lam = (lot.s1 - lot.s0) * (q - near) / GARDEN_M2_PER_TREE
        _small_trees(road, lot.side, lot.s0, lot.s1, near + 1.0, q - 1.0, rng.poisson(lam), rng, out,
                     GARDEN_CROWN_BASE)
    return q


# Steel crash barriers (German "einfache Schutzplanke", RPS 2009 / EN 1317): a W-beam rail 0.31 m
# deep, its top 0.75 m above the ground, on posts every 2 m behind it; they line arterial and
# rural roads beside open land (embankments, ditches). The rail's two ridges stand 3 cm proud of
# its groove, what a camera sees as two light bands and a dark one.
# Across the road the profile is 83 mm deep (drawn 0.08 m), 0.15 m behind the sidewalk's edge.
RAIL_TOP, RAIL_DEPTH, RAIL_RIDGE, RAIL_PROUD = 0.75, 0.31, 0.10, 0.03
RAIL_BACK, RAIL_THICK = 0.15, 0.08
POST_PITCH, POST_W, POST_D, POST_BELOW_TOP = 2.0, 0.10, 0.05, 0.05


def _guardrail(road: RoadLayout, side: int, s0: float, s1: float, out: _Meshes) -> None:
    """A crash barrier along the back of the sidewalk over [s0, s1]."""
    if s1 - s0 < 4.0:
        return
    ch, q, back = road.curb_height, RAIL_BACK, RAIL_BACK + RAIL_THICK
    lo = RAIL_TOP - RAIL_DEPTH
    posts = np.arange(s0 + POST_PITCH / 2, s1, POST_PITCH)
    for a, b in _pieces(s0, s1):
        ridge = _qbox(road, side, a, b, q, back, ch + lo, RAIL_RIDGE)
        if out.blocks(ridge):  # a piece in a keep-clear area is left out whole
            continue
        _add_solid(out, METAL, ridge)
        out.add(METAL, _qbox(road, side, a, b, q + RAIL_PROUD, back, ch + lo + RAIL_RIDGE,
                             RAIL_DEPTH - 2 * RAIL_RIDGE))
        out.add(METAL, _qbox(road, side, a, b, q, back, ch + RAIL_TOP - RAIL_RIDGE, RAIL_RIDGE))
        for s in posts[(posts >= a) & (posts < b)]:
            out.add(METAL, _qbox(road, side, s - POST_W / 2, s + POST_W / 2, back, back + POST_D, ch,
                                 RAIL_TOP - POST_BELOW_TOP))


def _open_land(road: RoadLayout, lot: Lot, rng: np.random.Generator, out: _Meshes,
               guardrail: float = 0.0) -> None:
    """A lawn or a meadow up to the buildings across the block, with park trees; with
    probability `guardrail` a crash barrier along the sidewalk (no draw at 0)."""
    side, ch = lot.side, road.curb_height
    far = _across_block(road, lot, 0.0, rng, out, gardens=False)
    lam = (lot.s1 - lot.s0) * far / PARK_M2_PER_TREE
    outer = _outer(road, side)
    for _ in range(rng.poisson(lam)):
        x, y = road.xy(rng.uniform(lot.s0, lot.s1), outer + side * rng.uniform(2.0, far - 2.0))
        _tree(out, x, y, ch, rng.uniform(*TREE_HEIGHT), rng.uniform(*CROWN_RADIUS), CLEAR_FOOTWAY, 0.25)
    s0, s1 = max(lot.s0, road.s_min), min(lot.s1, road.s_max)
    if guardrail > 0 and rng.uniform() < guardrail:
        _guardrail(road, side, s0, s1, out)
    if rng.uniform() < 0.5 or s1 <= s0:  # a lawn: the ground laid by _frontage_ground
        return
    h, ss = ch + rng.uniform(*MEADOW_HEIGHT), road.samples(s0, s1)
    out.add(FOLIAGE, _strip(road, ss, *sorted((outer + side * 0.5, outer + side * far)), h))
    face = _strip(road, ss, outer + side * 0.5, outer + side * 0.5, ch, h)
    out.add(FOLIAGE, _flip(face) if side < 0 else face)


def _green(road: RoadLayout, lot: Lot, rng: np.random.Generator, out: _Meshes) -> None:
    """A belt of shrubs and small trees behind a grass margin, the next street's buildings
    across the block behind it. Shrubs stand on a grid a mean radius apart across the belt and
    along it, each jittered by a third of that, so that they close into one mass; none reaches
    in front of the margin, and the trees' crowns clear the footway (CLEAR_FOOTWAY)."""
    side, ch, outer = lot.side, road.curb_height, _outer(road, lot.side)
    q0 = rng.uniform(*GREEN_MARGIN)
    q1 = q0 + rng.uniform(*GREEN_DEPTH)
    s0, s1 = max(lot.s0, road.s_min), min(lot.s1, road.s_max)
    r_mean = sum(SHRUB_BELT_RADIUS) / 2
    for q in np.arange(q0 + r_mean, q1, r_mean):
        for s in np.arange(s0 + r_mean / 2, s1, r_mean):
            r, h = rng.uniform(*SHRUB_BELT_RADIUS), rng.uniform(*SHRUB_BELT_HEIGHT)
            jitter = rng.uniform(-r_mean / 3, r_mean / 3, 2)
            across = max(q0 + r, min(q + jitter[1], q1 - r / 2))
            x, y = road.xy(s + jitter[0], outer + side * across)
            _ellipsoid(out, SHRUB_MASS, x, y, r, h / 2 / _SPHERE_TOP, ch + h / 2)
    _small_trees(road, side, s0, s1, q0 + 1.0, q1 - 1.0,
                 rng.poisson((s1 - s0) * (q1 - q0) / GREEN_M2_PER_TREE), rng, out,
                 (CLEAR_FOOTWAY, CLEAR_FOOTWAY))
    _across_block(road, lot, q1, rng, out, gardens=False)


def _lot(road: RoadLayout, lot: Lot, setback: float, rng: np.random.Generator, out: _Meshes,
         guardrail: float = 0.0) -> None:
    """Everything standing on one lot (its ground is laid by _frontage_ground)."""
    side, s0, s1, ch = lot.side, lot.s0, lot.s1, road.curb_height
    if lot.kind == "row":
        depth = _closed_row(road, side, s0, s1, setback, rng, out)
        _across_block(road, lot, setback + depth, rng, out)
    elif lot.kind == "houses":
        yard = rng.uniform(*FRONT_YARD)
        depth = _house_row(road, side, s0, s1, yard, rng, out, yard=True)
        _across_block(road, lot, yard + depth, rng, out)
    elif lot.kind == "green":
        _green(road, lot, rng, out)
    elif lot.kind == "open":
        _open_land(road, lot, rng, out, guardrail)
    else:  # car park: planting strips with trees, a hedge or nothing along the sidewalk, a store
        n_strips = round((lot.depth - PLANTING) / (2 * STALL_L + AISLE + PLANTING)) + 1
        outer = _outer(road, side)
        for i in range(n_strips):
            q = PLANTING / 2 + i * (2 * STALL_L + AISLE + PLANTING)
            d = outer + side * q
            step = STALLS_PER_TREE * STALL_W / (1.0 - road.curvature * d)
            for s in np.arange(s0 + 3.0 + rng.uniform(0, step), s1 - 3.0, step):
                x, y = road.xy(s, d)
                _tree(out, x, y, ch, rng.uniform(*SMALL_TREE_HEIGHT),
                      rng.uniform(*SMALL_CROWN_RADIUS), CLEAR_FOOTWAY, 0.15)
        _boundary(road, side, s0 + 3.0, s1 - 3.0, rng.choice(["hedge", "none"]), rng, out)
        q = lot.depth + rng.uniform(3.0, 10.0)
        length = (s1 - s0) * rng.uniform(0.4, 0.9)
        at = s0 + rng.uniform(0.0, s1 - s0 - length)
        depth = min(rng.uniform(*STORE_DEPTH), LAND_DEPTH - q - 1.0)
        if depth > 5.0:
            _add_building(out, rng, _qbox(road, side, at, at + length, q, q + depth, ch,
                                          rng.uniform(*STORE_HEIGHT)))


# Front boundaries of the other lots (clutter.front_boundary): a street's land is fenced, hedged or
# walled off from the sidewalk as the detached houses' yards are, along closed rows set back
# behind front gardens, open land and belts of green; the same kinds and sizes as the yards'
# (FENCE_HEIGHT, HEDGE_HEIGHT, WALL_HEIGHT), equally often. A row needs a front garden
# (ROW_GARDEN) for one; car parks keep their own hedge or nothing. SemanticKITTI's fence class
# takes 7.2 % of its returns; fences, crash barriers and low walls took 1.5 % of a scan of
# scenes/urban.yaml before these boundaries (benchmarks/return_classes.py).
FRONTED = ("row", "open", "green")
FRONT_KINDS = tuple(k for k in BOUNDARIES if k != "none")  # the yards' kinds, each always drawn
ROW_GARDEN = 1.5


def _front_boundaries(road: RoadLayout, plan: Frontage, setback: float, share: float,
                      rng: np.random.Generator, out: _Meshes) -> None:
    """With probability `share` per lot of a FRONTED kind, a hedge, fence or wall along the back
    of its sidewalk (pieces in keep-clear areas are left out, as every boundary's)."""
    for lot in plan.lots:
        if lot.kind not in FRONTED or (lot.kind == "row" and setback < ROW_GARDEN):
            continue
        if rng.uniform() < share:
            s0, s1 = max(lot.s0, road.s_min), min(lot.s1, road.s_max)
            _boundary(road, lot.side, s0, s1, FRONT_KINDS[int(rng.integers(len(FRONT_KINDS)))], rng, out)


def _side_street(road: RoadLayout, side: int, a: float, b: float, out: _Meshes) -> None:
    """A side street's carriageway [a, b] from the road's edge out to the land's far edge, its
    sidewalks and curbs; the band is kept clear of trees, poles and buildings."""
    curb = road.right_curb if side < 0 else road.left_curb
    outer, sw, ch = _outer(road, side), road.sidewalk_width, road.curb_height
    far = outer + side * LAND_DEPTH
    d0, d1 = sorted((curb, far))
    out.add(ASPHALT, _strip(road, road.samples(a, b), d0, d1, 0.0))
    w0, w1 = sorted((outer, far))
    out.add(SIDEWALK, _strip(road, road.samples(a - sw, a), w0, w1, ch))
    out.add(SIDEWALK, _strip(road, road.samples(b, b + sw), w0, w1, ch))
    for s, facing in ((a, 1.0), (b, -1.0)):  # curb faces towards the carriageway
        p0, p1 = road.xy(s, d0), road.xy(s, d1)
        v = np.array([[*p0, ch], [*p1, ch], [*p1, 0.0], [*p0, 0.0]])
        n = np.cross(v[1] - v[0], v[2] - v[0])
        t = np.array([np.cos(road.heading(s)), np.sin(road.heading(s)), 0.0]) * facing
        out.add(CONCRETE, Shape(v, _QUAD if n @ t > 0 else _QUAD[:, [0, 2, 1]]))
    out.clear.append(_quad_polygon(road, a - 0.5, b + 0.5, d0, d1))


def _frontage_ground(road: RoadLayout, plan: Frontage, ground: Material, out: _Meshes) -> None:
    """Asphalt, the cross street, sidewalks and curbs broken by side streets, and each lot's
    ground (car parks paved at sidewalk height) out to LAND_DEPTH."""
    ch, sw = road.curb_height, road.sidewalk_width
    _carriageway(road, out)
    if road.cross_s is not None:
        out.clear.append(_cross_street(road, out.add, LAND_DEPTH + sw))
    for side in (-1, 1):
        curb, outer = (road.right_curb if side < 0 else road.left_curb), _outer(road, side)
        lo, hi = sorted((curb, outer))
        spans = _spans(road, 0.0)
        for a, b in plan.mouths[side]:
            spans = _cut(spans, a, b)
            _side_street(road, side, a, b, out)
        for s0, s1 in spans:
            ss = road.samples(s0, s1)
            out.add(SIDEWALK, _strip(road, ss, lo, hi, ch))
            face = _strip(road, ss, curb, curb, 0.0, ch)
            out.add(CONCRETE, face if side < 0 else _flip(face))
    for lot in plan.lots:
        s0, s1 = max(lot.s0, road.s_min), min(lot.s1, road.s_max)
        if s1 <= s0:
            continue
        ss, outer = road.samples(s0, s1), _outer(road, lot.side)
        q = 0.0
        if lot.depth > 0:  # car park paving
            out.add(ASPHALT, _strip(road, ss, *sorted((outer, outer + lot.side * lot.depth)), ch))
            q = lot.depth
        out.add(ground, _strip(road, ss, *sorted((outer + lot.side * q, outer + lot.side * LAND_DEPTH)), ch))


def _street_trees(road: RoadLayout, side: int, per_100m: float, rng: np.random.Generator,
                  out: _Meshes) -> None:
    """Street trees on the sidewalk, sized as GALK's street trees; crowns reaching over the
    carriageway start at 4.5 m, others at 2.5 m."""
    ch, sw = road.curb_height, road.sidewalk_width
    curb = road.right_curb if side < 0 else road.left_curb
    inset = min(1.0, sw / 2)
    for st in np.sort(rng.uniform(road.s_min, road.s_max, rng.poisson(per_100m * (road.s_max - road.s_min) / 100.0))):
        h, r = rng.uniform(*TREE_HEIGHT), rng.uniform(*CROWN_RADIUS)
        x, y = road.xy(st, _outer(road, side) - side * inset)
        over_road = r > abs(_outer(road, side) - side * inset - curb)
        _tree(out, x, y, ch, h, r, CLEAR_ROAD if over_road else rng.uniform(CLEAR_FOOTWAY, CLEAR_ROAD))


def _build_frontage(road: RoadLayout, plan: Frontage, clutter: dict, ground: Material,
                    seed: int, out: _Meshes) -> None:
    """The frontage world: ground, lots, street trees, poles (own random streams per part)."""
    _frontage_ground(road, plan, ground, out)
    _markings(road, out)
    rng = np.random.default_rng([seed, 2])
    setback = float(clutter["building_setback"])
    for lot in plan.lots:
        _lot(road, lot, setback, rng, out, float(clutter.get("guardrail", 0.0)))
    share = float(clutter.get("front_boundary", 0.0))
    if share > 0:  # its own stream: every other draw of the world stays as it was
        _front_boundaries(road, plan, setback, share, np.random.default_rng([seed, 6]), out)
    rng = np.random.default_rng([seed, 3])
    for side in (-1, 1):
        _street_trees(road, side, clutter["trees_per_100m"], rng, out)
        if clutter["pole_spacing"] > 0:
            _poles(road, side, road.right_curb if side < 0 else road.left_curb,
                   clutter["pole_spacing"], rng, out)


# --- Street furniture (clutter.furniture) -----------------------------------------------------
# On the sidewalks of both street models, after everything else, from its own random stream; each
# piece keeps off the keep-clear areas, the obstacles lower than its top and the pieces before it.
# `clutter.furniture` scales the densities below. German rules again, KITTI being Karlsruhe's.
#
# Traffic signs. More than 20 million in Germany, on average one every 28 m of road, motorways
# included (press figures): 3.6 per 100 m of road, 1.8 per side. VwV-StVO: lower edge 2.0 m above
# footways; the edge nearest the carriageway 0.5 m from it in town (never less than 0.3 m); posts
# and backs grey (METAL), the common post a 60.3 mm steel tube. Sizes: VwV-StVO size 2, the one
# for 50-100 km/h: circle 600 mm, triangle 900 mm a side, square 600 mm; the stop octagon and the
# priority diamond taken as 600 mm (no table at hand). Kinds equally often (no survey found).
SIGNS_PER_100M = 1.8
SIGN_LOWER_EDGE, SIDE_CLEARANCE, SIGN_POST_R = 2.0, 0.5, 0.03
# kind: outer (corners, circumradius m, phase deg) and sheeting, inner field (or None) and sheeting;
# the fields' proportions read off the StVO's drawings.
SIGNS = {
    "prohibition": ((12, 0.30, 0.0), SIGN_RED, (12, 0.24, 0.0), SIGN_WHITE),
    "mandatory": ((12, 0.30, 0.0), SIGN_BLUE, None, None),
    "no_stopping": ((12, 0.30, 0.0), SIGN_RED, (12, 0.24, 0.0), SIGN_BLUE),
    "warning": ((3, 0.52, 90.0), SIGN_RED, (3, 0.37, 90.0), SIGN_WHITE),
    "yield": ((3, 0.52, -90.0), SIGN_RED, (3, 0.37, -90.0), SIGN_WHITE),
    "stop": ((8, 0.325, 22.5), SIGN_RED, None, None),
    "priority": ((4, 0.42, 0.0), SIGN_WHITE, (4, 0.30, 0.0), SIGN_YELLOW),
    "crossing": ((4, 0.42, 45.0), SIGN_BLUE, (3, 0.25, 90.0), SIGN_WHITE),
}
# Traffic signals at every corner of the intersection, each facing the traffic that arrives there
# (the generated intersection joins multi-lane urban streets: signalised; no survey of the share).
# Lower edge of the head 2.10 m above the footway, 0.3 m at least from the carriageway (RSA/RiLSA);
# a three-lamp head of 200 mm lenses, about 0.30 x 0.85 x 0.25 m in a 0.55 x 1.05 m black board
# (makers' drawings; no standard found), on a mast of about 140 mm.
SIGNAL_LOWER_EDGE, SIGNAL_MAST_R = 2.10, 0.07
# Which lamp is lit: RiLSA's amber lasts 3 s at 50 km/h in cycles of typically 60-90 s, so about
# 5 % of the time; red and green share the rest (no survey). The cross street shows red unless the
# main road does. Lens colours (linear RGB) lit and dark.
SIGNAL_PHASES, SIGNAL_SHARES = ("red", "amber", "green"), (0.475, 0.05, 0.475)
LENSES = {"red": ((1.0, 0.06, 0.03), (0.10, 0.02, 0.02)), "amber": ((1.0, 0.50, 0.02), (0.10, 0.07, 0.01)),
          "green": ((0.08, 1.0, 0.45), (0.02, 0.09, 0.06))}
# Litter bins: Hamburg has 8,850 public bins, most of 42 l, hung on posts (Hamburger Abendblatt),
# along about 4,000 km of streets: 0.22 per 100 m of street, 0.11 per side. A 42 l drum is 0.36 m
# across and 0.45 m high; its top at 1.0 m (no figure found). Colours: Berlin's orange, Hamburg's
# red, moss green and anthracite (RAL 2000, 3000, 6005, 7016), equally often (no survey found).
BINS_PER_100M = 0.11
BIN_R, BIN_H, BIN_TOP = 0.18, 0.45, 1.0
BIN_COLOURS = ((0.70, 0.16, 0.0), (0.45, 0.01, 0.01), (0.03, 0.06, 0.04), (0.02, 0.03, 0.03))
# Bollards keeping cars off the sidewalk: steel tubes of 76-108 mm, 0.9-1.0 m high, most with a
# white retro-reflective band (makers' catalogues; no standard found), in rows of 3-6 with gaps a
# car cannot pass (1.4 m between centres). Rows per side: no survey found, 0.5 per 100 m.
BOLLARD_ROWS_PER_100M = 0.5
BOLLARD_R, BOLLARD_H, BOLLARD_PITCH, BOLLARD_ROW = 0.045, 0.95, 1.4, (3, 7)
# Cycle stands (Anlehnbuegel): 48 mm tube, about 0.8 m high and 1.0 m long, 1.2 m apart for two
# bikes each (ADFC's recommendation), across the sidewalk, in groups of 2-6; only on sidewalks of
# at least 2.5 m, RASt 06's standard width. Groups per side: no survey found, 0.3 per 100 m.
STAND_GROUPS_PER_100M = 0.3
STAND_R, STAND_H, STAND_L, STAND_PITCH, STAND_GROUP, STAND_SIDEWALK = 0.024, 0.8, 1.0, 1.2, (2, 7), 2.5
# Parked bicycles: each side of a stand holds one with this probability (a judgement: no survey of
# how full KITTI's stands were), alongside the bar (its frame BIKE_GAP from the bar's axis), front
# wheel either way: the cyclist's bicycle (simgen.meshes.bicycle) scaled evenly to the length of
# KITTI's Cyclist labels (1.76 m, simgen.meshes.SIZE_STATS). KITTI's Cyclist is a rider on a
# bicycle; it labels no parked one, and neither does the generator: they are scenery, for the
# camera and the LiDAR alike.
STAND_OCCUPANCY = 0.5
BIKE_L, BIKE_GAP = 1.76, 0.12


def _posed(m: Shape | trimesh.Trimesh, T: np.ndarray) -> Shape:
    return Shape(m.vertices @ T[:3, :3].T + T[:3, 3], m.faces)


def _regular(n: int, r: float, phase_deg: float) -> np.ndarray:
    """A regular polygon's corners (y, z) about the origin."""
    a = np.radians(phase_deg) + 2 * np.pi * np.arange(n) / n
    return np.c_[r * np.cos(a), r * np.sin(a)]


def _plate(poly: np.ndarray, x0: float, x1: float, z: float) -> trimesh.Trimesh:
    """A flat plate of a convex outline (y, z about height z), facing +x from x0 to x1."""
    return extrude(poly + [0.0, z], 0, x0, x1)


def _column(x: float, y: float, r: float, z0: float, z1: float) -> Shape:
    return _placed(_UNIT_CYLINDER, [r, r, z1 - z0], [x, y, (z0 + z1) / 2])


class _Furnisher:
    """Places pieces of furniture (parts in the world frame and their obstacles) where they fit."""

    def __init__(self, road: RoadLayout, out: _Meshes):
        self.road, self.out = road, out
        self.bases = np.array([o.base for o in out.obstacles])
        self.tree = shapely.STRtree([o.polygon for o in out.obstacles])
        self.placed: list[shapely.Polygon] = []

    def pose(self, side: int, s: float, inset: float, yaw: float = 0.0) -> np.ndarray:
        """World pose `inset` metres behind the curb of `side`, on the sidewalk, x turned by yaw
        from the road's heading."""
        curb = self.road.right_curb if side < 0 else self.road.left_curb
        return self.road.pose(s, curb + side * inset, 0.0, yaw)

    def add(self, parts: list[tuple[Material, Shape]], obstacles: list[Obstacle],
            corner: bool = False) -> bool:
        """Adds the piece unless it stands in a keep-clear area (at a corner: a sight line only),
        on an obstacle lower than its top, or on a piece placed before."""
        fp, top = _extent(parts)
        if not self._free(fp, top, self.out.sight if corner else self.out.clear, self.placed):
            return False
        self._put(parts, obstacles)
        self.placed.append(fp)
        return True

    def add_beside(self, parts: list[tuple[Material, Shape]], margin: float) -> bool:
        """Adds a piece that belongs to the one placed last (a bicycle at its stand): tested as
        `add` does, but not against that piece; its footprint, grown by `margin`, becomes an
        obstacle and joins that piece's."""
        fp, top = _extent(parts)
        if not self._free(fp, top, self.out.clear, self.placed[:-1]):
            return False
        self._put(parts, [Obstacle(fp.buffer(margin))])
        self.placed[-1] = self.placed[-1].union(fp)
        return True

    def _free(self, fp: shapely.Polygon, top: float, keep_clear: list, placed: list) -> bool:
        if any(fp.intersects(c) for c in keep_clear):
            return False
        hits = self.tree.query(fp, predicate="intersects")
        return not (np.any(self.bases[hits] < top) or any(fp.intersects(p) for p in placed))

    def _put(self, parts: list[tuple[Material, Shape]], obstacles: list[Obstacle]) -> None:
        for mat, m in parts:
            self.out.add(mat, m)
        self.out.obstacles += obstacles


def _extent(parts: list[tuple[Material, Shape]]) -> tuple[shapely.Polygon, float]:
    """A piece's footprint (the convex hull of its vertices seen from above) and its top."""
    v = np.concatenate([m.vertices for _, m in parts])
    return shapely.convex_hull(shapely.MultiPoint(v[:, :2])), float(v[:, 2].max())


def _sign(f: _Furnisher, side: int, s: float, kind: str) -> None:
    """A sign on its post behind the curb, facing the traffic on its side (the right side's
    faces look back along -s)."""
    (n, r, ph), outer_mat, inner, inner_mat = SIGNS[kind]
    outer = _regular(n, r, ph)
    ch = f.road.curb_height
    z = ch + SIGN_LOWER_EDGE - outer[:, 1].min()
    T = f.pose(side, s, SIDE_CLEARANCE + outer[:, 0].max(), np.pi if side < 0 else 0.0)
    post = _column(-0.02 - SIGN_POST_R, 0.0, SIGN_POST_R, ch, z + outer[:, 1].max())
    local = [(METAL, post), (METAL, _plate(outer, -0.02, 0.0, z)), (outer_mat, _plate(outer, 0.0, 0.003, z))]
    if inner is not None:
        local.append((inner_mat, _plate(_regular(*inner), 0.003, 0.006, z)))
    parts = [(mat, _posed(m, T)) for mat, m in local]
    plate = shapely.convex_hull(shapely.MultiPoint(np.concatenate([m.vertices[:, :2] for _, m in parts[1:]])))
    f.add(parts, [Obstacle(_footprint(parts[0][1]).buffer(0.1)),
                  Obstacle(plate, base=ch + SIGN_LOWER_EDGE)])


def _signal(f: _Furnisher, T: np.ndarray, lit: str) -> None:
    """A signal head on its mast at pose T (x: where the lamps face), `lit` the lamp that is on."""
    ch, m = f.road.curb_height, SIGNAL_MAST_R
    z0 = ch + SIGNAL_LOWER_EDGE
    local = [(METAL, _column(0.0, 0.0, m, ch, z0 + 1.05)),
             (TRIM, box(m + 0.20, m + 0.215, -0.275, 0.275, z0, z0 + 1.05)),
             (TRIM, box(m, m + 0.25, -0.15, 0.15, z0 + 0.10, z0 + 0.95))]
    for k, phase in enumerate(SIGNAL_PHASES):  # red on top
        colour = LENSES[phase][0 if phase == lit else 1]
        local.append((signal_lens(colour), _plate(_regular(8, 0.10, 22.5), m + 0.25, m + 0.265,
                                                   z0 + 0.795 - 0.27 * k)))
    parts = [(mat, _posed(mesh, T)) for mat, mesh in local]
    head = shapely.convex_hull(shapely.MultiPoint(np.concatenate([x.vertices[:, :2] for _, x in parts[1:]])))
    f.add(parts, [Obstacle(_footprint(parts[0][1]).buffer(0.1)), Obstacle(head, base=z0)], corner=True)


def _signals(f: _Furnisher, rng: np.random.Generator) -> None:
    """One signal at each corner of the intersection, SIGNAL clearance from both curbs, facing
    the traffic that arrives at that corner (right-hand traffic)."""
    road = f.road
    main = SIGNAL_PHASES[int(rng.choice(3, p=SIGNAL_SHARES))]
    cross = "green" if main == "red" else "red"
    off = SIDE_CLEARANCE + 0.15  # the head's half width beyond the mast
    # (side, before the crossing, lamp lit, facing: main-road traffic along -s/+s, cross traffic -y/+y)
    for side, before, lit, yaw in ((-1, True, main, np.pi), (1, False, main, 0.0),
                                   (-1, False, cross, -np.pi / 2), (1, True, cross, np.pi / 2)):
        s = road.cross_s + (-1 if before else 1) * (road.cross_half_width + off)
        _signal(f, f.pose(side, s, off, yaw), lit)


def _bin(f: _Furnisher, side: int, s: float, colour) -> None:
    """A drum hung on the side of its post."""
    ch = f.road.curb_height
    T = f.pose(side, s, SIDE_CLEARANCE + BIN_R)
    local = [(METAL, _column(0.0, 0.0, SIGN_POST_R, ch, ch + BIN_TOP + 0.1)),
             (paint_material("bin", colour), _column(SIGN_POST_R + BIN_R, 0.0, BIN_R, ch + BIN_TOP - BIN_H,
                                                     ch + BIN_TOP))]
    parts = [(mat, _posed(m, T)) for mat, m in local]
    f.add(parts, [Obstacle(_footprint(m).buffer(0.05)) for _, m in parts])


def _bollards(f: _Furnisher, side: int, s: float, n: int) -> None:
    """A row of n bollards along the curb from s, each with a white band below its top."""
    ch = f.road.curb_height
    parts = []
    for k in range(n):
        T = f.pose(side, s + k * BOLLARD_PITCH, SIDE_CLEARANCE + BOLLARD_R)
        parts += [(METAL, _posed(_column(0.0, 0.0, BOLLARD_R, ch, ch + BOLLARD_H), T)),
                  (SIGN_WHITE, _posed(_column(0.0, 0.0, BOLLARD_R + 0.003, ch + BOLLARD_H - 0.15,
                                              ch + BOLLARD_H - 0.08), T))]
    f.add(parts, [Obstacle(_footprint(m).buffer(0.1)) for _, m in parts[::2]])


def _stands(f: _Furnisher, side: int, s: float, n: int, bikes: np.random.Generator) -> None:
    """n cycle stands across the sidewalk from s: two legs and a top bar each; then, where the
    stands were placed, the bicycles parked at them (their own random stream: the furniture drawn
    after them stays where it was)."""
    ch, r, h, half = f.road.curb_height, STAND_R, STAND_H, STAND_L / 2
    parts = []
    for k in range(n):
        T = f.pose(side, s + k * STAND_PITCH, SIDE_CLEARANCE + half, np.pi / 2)
        for m in (box(-half, -half + 2 * r, -r, r, ch, ch + h), box(half - 2 * r, half, -r, r, ch, ch + h),
                  box(-half, half, -r, r, ch + h - 2 * r, ch + h)):
            parts.append((METAL, _posed(m, T)))
    parked = []  # (stand, side of its bar, heading) of each bicycle
    for k in range(n):
        for gap in (-BIKE_GAP, BIKE_GAP):
            if bikes.uniform() < STAND_OCCUPANCY:
                parked.append((k, gap, np.pi / 2 if bikes.uniform() < 0.5 else -np.pi / 2))
    if not f.add(parts, [Obstacle(_footprint(m).buffer(0.1)) for _, m in parts]):
        return
    for k, gap, yaw in parked:
        T = f.pose(side, s + k * STAND_PITCH + gap, SIDE_CLEARANCE + BIKE_L / 2, yaw)
        T[2, 3] += ch
        f.add_beside([(p.material, _posed(p.mesh, T)) for p in _parked_bicycle()], 0.05)


@functools.cache
def _parked_bicycle() -> tuple[Part, ...]:
    """A bicycle BIKE_L long, scaled evenly (round wheels), origin on the ground at its middle."""
    parts = bicycle()
    v = np.concatenate([np.asarray(p.mesh.vertices) for p in parts])
    l, w, h = (v.max(axis=0) - v.min(axis=0)) * (BIKE_L / np.ptp(v[:, 0]))
    return tuple(fit_parts(parts, h, w, l))


def _furniture(road: RoadLayout, clutter: dict, seed: int, out: _Meshes) -> None:
    """Signals at the intersection, then signs, bins, bollards and cycle stands (with the bicycles
    parked at them) along both sidewalks, Poisson in number at the densities above times
    `clutter.furniture`."""
    scale = float(clutter.get("furniture", 0.0))  # scenery parameters from before it: none
    if scale <= 0:
        return
    rng = np.random.default_rng([seed, 4])
    bikes = np.random.default_rng([seed, 5])
    f = _Furnisher(road, out)
    if road.cross_s is not None:
        _signals(f, rng)
    length = (road.s_max - road.s_min) / 100.0
    for side in (-1, 1):
        for s in rng.uniform(road.s_min, road.s_max, rng.poisson(scale * SIGNS_PER_100M * length)):
            _sign(f, side, s, list(SIGNS)[int(rng.integers(len(SIGNS)))])
        for s in rng.uniform(road.s_min, road.s_max, rng.poisson(scale * BINS_PER_100M * length)):
            _bin(f, side, s, BIN_COLOURS[int(rng.integers(len(BIN_COLOURS)))])
        for s in rng.uniform(road.s_min, road.s_max, rng.poisson(scale * BOLLARD_ROWS_PER_100M * length)):
            _bollards(f, side, s, int(rng.integers(*BOLLARD_ROW)))
        groups = rng.poisson(scale * STAND_GROUPS_PER_100M * length)
        for s in rng.uniform(road.s_min, road.s_max, groups if road.sidewalk_width >= STAND_SIDEWALK else 0):
            _stands(f, side, s, int(rng.integers(*STAND_GROUP)), bikes)


def _merged(meshes: list[Shape | trimesh.Trimesh]) -> trimesh.Trimesh:
    """One mesh of many: trimesh.util.concatenate's vertices and faces (stacked, faces offset)
    without its per-mesh type checks, visuals and metadata, which cost ~50 ms a frame."""
    starts = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    faces = np.concatenate([m.faces + start for m, start in zip(meshes, starts)])
    return trimesh.Trimesh(np.concatenate([m.vertices for m in meshes]), faces, process=False)


def build_scenery(params: dict) -> tuple[list[Part], list[Obstacle]]:
    """Static parts (world frame) and their footprints, from the scenery parameters.

    Everything is planned on a flat road and then laid onto the road's vertical profile
    (`simgen.relief`); the footprints stay in plan view, their bases relative to the road.

    `params["keep_clear"]` (optional): a list of (x, y) polygon vertices where no building, tree
    or pole may stand, e.g. the line of sight of an orbit camera to its target. With
    `clutter.frontage` the sides are lots and side streets (plan_frontage), else one closed row.
    """
    road = RoadLayout(**params["road"])
    clutter = params["clutter"]
    ground, buildings, tree_factor, woods = ENVIRONMENTS[clutter.get("environment", "city")]
    out = _Meshes([shapely.Polygon(params["keep_clear"])] if params.get("keep_clear") else [])
    plan = plan_frontage(params)
    if plan is not None:
        _build_frontage(road, plan, clutter, ground, int(params["seed"]), out)
        _furniture(road, clutter, int(params["seed"]), out)
        parts = [Part(_merged(ms), mat) for mat, ms in out.by_mat.items()]
        return drape_parts(parts, road), out.obstacles
    rng = np.random.default_rng(params["seed"])
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
    _furniture(road, clutter, int(params["seed"]), out)
    parts = [Part(_merged(ms), mat) for mat, ms in out.by_mat.items()]
    return drape_parts(parts, road), out.obstacles
