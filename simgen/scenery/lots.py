"""The frontage world (clutter.frontage): each lot's houses, rows, car parks, open land and belts
of green, their boundaries, the side streets, the ground, street trees and poles, as planned by
simgen.scenery.frontage.plan_frontage."""

from __future__ import annotations

import itertools

import numpy as np
import shapely

from ..materials import (ASPHALT, BARK, CONCRETE, FACADE_REFLECTIVITY, FENCE, FOLIAGE, METAL, SHRUB_MASS,
                         SIDEWALK)
from ..meshes import Shape
from ..road import RoadLayout
from ..world import Material
from .frontage import (AISLE, BACK_GARDEN, BLOCK_DEPTH, BOUNDARIES, BOUNDARY_MIN, BOUNDARY_SHARE,
                       CLEAR_FOOTWAY, CLEAR_ROAD, CROWN_RADIUS, DRIVE_GAP, FENCE_HEIGHT, FRONT_YARD, Frontage,
                       GARAGE, GARAGE_APRON, GARAGE_HEIGHT, GARDEN_CROWN_BASE, GARDEN_M2_PER_TREE,
                       GREEN_DEPTH, GREEN_M2_PER_TREE, GREEN_MARGIN, HEDGE_DEPTH, HEDGE_HEIGHT, HOUSE_DEPTH,
                       HOUSE_HEIGHT, HOUSE_LENGTH, LAND_DEPTH, Lot, MEADOW_HEIGHT, PARK_M2_PER_TREE, PLANTING,
                       PLOT_SLACK, ROW_DEPTH, ROW_HEIGHT, ROW_LENGTH, SHRUB_BELT_HEIGHT, SHRUB_BELT_RADIUS,
                       SHRUB_RADIUS, SMALL_CROWN_RADIUS, SMALL_TREE_HEIGHT, STALLS_PER_TREE, STALL_L, STALL_W,
                       STORE_DEPTH, STORE_HEIGHT, TREE_HEIGHT, WALL_HEIGHT, YARD_M2_PER_TREE,
                       YARD_SHRUBS_PER_TREE, _outer, cut)
from .parts import (FACADES, Obstacle, QUAD, SPHERE_TOP, UNIT_BOX, UNIT_CYLINDER, UNIT_SPHERES, _Meshes,
                    _spans, cross_street, discs, flip, footprint, placed_many, strip, uniform)
from .street import carriageway, markings, poles


def _unit_box_gather() -> np.ndarray:
    """Each UNIT_BOX vertex as indices into the ten corner values _qbox computes: x at 2 ix + iy,
    y at 4 + 2 ix + iy, z at 8 + iz, i 1 where the vertex takes the axis's higher value."""
    ix, iy, iz = (UNIT_BOX.vertices > UNIT_BOX.vertices.min(axis=0)).T.astype(int)
    return np.column_stack((2 * ix + iy, 4 + 2 * ix + iy, 8 + iz))


_UNIT_BOX_VALUES = [tuple(np.unique(axis).tolist()) for axis in UNIT_BOX.vertices.T]  # lower, higher
_UNIT_BOX_GATHER = _unit_box_gather()


def _qbox(road: RoadLayout, side: int, s0: float, s1: float, q0: float, q1: float, z: float,
          h: float) -> Shape:
    """A box over [s0, s1] along the road and q0..q1 metres behind the sidewalk of `side`, its
    long axes along the road's heading at the box's centre: the unit box scaled, turned and
    moved, each distinct corner coordinate computed once in plain floats and gathered (numpy's
    per call cost was most of a box's)."""
    s, d = (s0 + s1) / 2, _outer(road, side) + side * (q0 + q1) / 2
    psi = road.curvature * s
    c, sn = np.cos(psi), np.sin(psi)
    (lx0, lx1), (ly0, ly1), (lz0, lz1) = ((u0 * e, u1 * e) for (u0, u1), e in
                                          zip(_UNIT_BOX_VALUES, (s1 - s0, q1 - q0, h)))
    x, y = road.xy(s, d)
    corners = np.array([x + c * lx0 - sn * ly0, x + c * lx0 - sn * ly1, x + c * lx1 - sn * ly0,
                        x + c * lx1 - sn * ly1, y + sn * lx0 + c * ly0, y + sn * lx0 + c * ly1,
                        y + sn * lx1 + c * ly0, y + sn * lx1 + c * ly1, lz0 + z + h / 2, lz1 + z + h / 2])
    return Shape(corners[_UNIT_BOX_GATHER], UNIT_BOX.faces)


def _quad_polygon(road: RoadLayout, s0: float, s1: float, d0: float, d1: float) -> shapely.Polygon:
    ss = road.samples(s0, s1)
    return shapely.Polygon(np.concatenate([road.xy(ss, d0), road.xy(ss[::-1], d1)]))


def _drive_mouth(road: RoadLayout, side: int, s0: float, s1: float, out: _Meshes) -> None:
    """Keeps the parking strip in front of a drive or a car park's entrance [s0, s1] free of
    parked vehicles (StVO section 12(3) no. 3: no parking in front of a property's way in or
    out): a footprint over the strip, from the kerb to the lane's edge, that actors may not
    overlap and nothing is drawn on."""
    if road.parks(side):
        d0, d1 = ((road.right_curb, road.right_lane_edge) if side < 0
                  else (road.left_lane_edge, road.left_curb))
        out.obstacles.append(Obstacle(_quad_polygon(road, s0, s1, d0, d1)))


def _add_building(out: _Meshes, rng: np.random.Generator, m: Shape) -> None:
    fp = footprint(m)
    if out.blocked(fp):
        return
    out.add(Material("facade", FACADES[int(rng.integers(len(FACADES)))], FACADE_REFLECTIVITY), m)
    out.obstacles.append(Obstacle(fp))


def _trees(out: _Meshes, xy: np.ndarray, z: float, height, r, base, trunk_r: float) -> None:
    """Trees at (n, 2) plan positions: trunks up to `base` above z, ellipsoid crowns of radius r
    from base to height; those whose crowns would reach into a keep-clear area are left out.
    Built all at once (placed_many, discs), with the bits of one tree at a time."""
    if not len(xy):
        return
    height, r, base = np.broadcast_arrays(height, r, base)
    x, y = xy[:, 0], xy[:, 1]
    crowns = discs(x, y, r, 8)
    keep = out.clear_of(crowns)
    if not keep.any():
        return
    x, y, height, r, base, crowns = x[keep], y[keep], height[keep], r[keep], base[keep], crowns[keep]
    rz = np.maximum(0.5, (height - base) / 2)
    t = np.full(len(x), trunk_r)
    out.add(BARK, placed_many(UNIT_CYLINDER, np.column_stack((t, t, base + rz)),
                              np.column_stack((x, y, z + (base + rz) / 2))))
    out.add(FOLIAGE, placed_many(UNIT_SPHERES[1], np.column_stack((r, r, rz)),
                                 np.column_stack((x, y, z + base + rz))))
    for trunk, crown, b in zip(discs(x, y, trunk_r + 0.1, 4), crowns, (z + base).tolist()):
        out.obstacles += [Obstacle(trunk), Obstacle(crown, base=b)]


def _ellipsoids(out: _Meshes, mat: Material, xy: np.ndarray, r: np.ndarray, rz: np.ndarray,
                cz: np.ndarray) -> None:
    """Coarse ellipsoids of radii r across and rz up about (n, 2) plan positions and heights cz,
    their footprints obstacles; those that would reach into a keep-clear area are left out."""
    if not len(xy):
        return
    r, rz, cz = np.broadcast_arrays(r, rz, cz)
    fps = discs(xy[:, 0], xy[:, 1], r, 4)
    keep = out.clear_of(fps)
    if not keep.any():
        return
    x, y, r, rz, cz = xy[keep, 0], xy[keep, 1], r[keep], rz[keep], cz[keep]
    out.add(mat, placed_many(UNIT_SPHERES[0], np.column_stack((r, r, rz)), np.column_stack((x, y, cz))))
    out.obstacles += [Obstacle(fp) for fp in fps[keep]]


def _shrubs(out: _Meshes, xy: np.ndarray, z: float, r: np.ndarray) -> None:
    _ellipsoids(out, FOLIAGE, xy, r, 0.7 * r, z + 0.7 * r)


def _small_trees(road: RoadLayout, side: int, s0: float, s1: float, q0: float, q1: float,
                 n: int, rng: np.random.Generator, out: _Meshes, base: tuple[float, float]) -> None:
    """n small-crowned trees over [s0, s1] x [q0, q1] behind the sidewalk, crowns from `base`;
    each tree's draws in turn: height, crown radius, s, q, crown base."""
    u = rng.random((n, 5))
    xy = road.xy(uniform((s0, s1), u[:, 2]), _outer(road, side) + side * uniform((q0, q1), u[:, 3]))
    _trees(out, xy, road.curb_height, uniform(SMALL_TREE_HEIGHT, u[:, 0]), uniform(SMALL_CROWN_RADIUS, u[:, 1]),
           uniform(base, u[:, 4]), 0.12)


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
    fp = footprint(m)
    if not out.blocked(fp):
        out.add(mat, m)
        out.obstacles.append(Obstacle(fp))


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
            _drive_mouth(road, side, gap, gap + DRIVE_GAP, out)
            # the side boundary (to the previous plot) and the rear one, behind the garden
            h, t, mat = _boundary_style(BOUNDARIES[int(rng.integers(len(BOUNDARIES) - 1))], rng)
            rear = q + depth + rng.uniform(*BACK_GARDEN)
            _add_solid(out, mat, _qbox(road, side, s, s + t, 1.2, rear, ch, h))
            for a, b in _pieces(s, s + plot):
                _add_solid(out, mat, _qbox(road, side, a, b, rear, rear + t, ch, h))
            lam = rng.uniform() * plot * q / YARD_M2_PER_TREE
            _small_trees(road, side, s + 1.0, s + plot - 1.0, 1.5, q - 1.0, rng.poisson(lam), rng, out,
                         (CLEAR_FOOTWAY, CLEAR_FOOTWAY))
            u = rng.random((rng.poisson(YARD_SHRUBS_PER_TREE * lam), 3))  # each shrub's s, q, radius
            xy = road.xy(uniform((s + 0.5, s + plot - 0.5), u[:, 0]),
                         _outer(road, side) + side * uniform((1.5, q - 0.5), u[:, 1]))
            _shrubs(out, xy, ch, uniform(SHRUB_RADIUS, u[:, 2]))
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
    u = rng.random((rng.poisson(lam), 4))  # each tree's s, q, height, crown radius
    xy = road.xy(uniform((lot.s0, lot.s1), u[:, 0]), outer + side * uniform((2.0, far - 2.0), u[:, 1]))
    _trees(out, xy, ch, uniform(TREE_HEIGHT, u[:, 2]), uniform(CROWN_RADIUS, u[:, 3]), CLEAR_FOOTWAY, 0.25)
    s0, s1 = max(lot.s0, road.s_min), min(lot.s1, road.s_max)
    if guardrail > 0 and rng.uniform() < guardrail:
        _guardrail(road, side, s0, s1, out)
    if rng.uniform() < 0.5 or s1 <= s0:  # a lawn: the ground laid by _frontage_ground
        return
    h, ss = ch + rng.uniform(*MEADOW_HEIGHT), road.samples(s0, s1)
    out.add(FOLIAGE, strip(road, ss, *sorted((outer + side * 0.5, outer + side * far)), h))
    face = strip(road, ss, outer + side * 0.5, outer + side * 0.5, ch, h)
    out.add(FOLIAGE, flip(face) if side < 0 else face)


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
    q, s = (g.ravel() for g in np.meshgrid(np.arange(q0 + r_mean, q1, r_mean),
                                          np.arange(s0 + r_mean / 2, s1, r_mean), indexing="ij"))
    u = rng.random((len(q), 4))  # each shrub's radius, height and jitter along and across
    r, h = uniform(SHRUB_BELT_RADIUS, u[:, 0]), uniform(SHRUB_BELT_HEIGHT, u[:, 1])
    jitter = uniform((-r_mean / 3, r_mean / 3), u[:, 2:])
    across = np.maximum(q0 + r, np.minimum(q + jitter[:, 1], q1 - r / 2))
    xy = road.xy(s + jitter[:, 0], outer + side * across)
    _ellipsoids(out, SHRUB_MASS, xy, r, h / 2 / SPHERE_TOP, ch + h / 2)
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
            ss = np.arange(s0 + 3.0 + rng.uniform(0, step), s1 - 3.0, step)
            u = rng.random((len(ss), 2))  # each tree's height and crown radius
            _trees(out, road.xy(ss, d), ch, uniform(SMALL_TREE_HEIGHT, u[:, 0]),
                   uniform(SMALL_CROWN_RADIUS, u[:, 1]), CLEAR_FOOTWAY, 0.15)
        _boundary(road, side, s0 + 3.0, s1 - 3.0, rng.choice(["hedge", "none"]), rng, out)
        for a in (s0, s1 - 3.0):  # the aisles open to the street at both ends
            _drive_mouth(road, side, a, a + 3.0, out)
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
    out.add(ASPHALT, strip(road, road.samples(a, b), d0, d1, 0.0))
    w0, w1 = sorted((outer, far))
    out.add(SIDEWALK, strip(road, road.samples(a - sw, a), w0, w1, ch))
    out.add(SIDEWALK, strip(road, road.samples(b, b + sw), w0, w1, ch))
    for s, facing in ((a, 1.0), (b, -1.0)):  # curb faces towards the carriageway
        p0, p1 = road.xy(s, d0), road.xy(s, d1)
        v = np.array([[*p0, ch], [*p1, ch], [*p1, 0.0], [*p0, 0.0]])
        n = np.cross(v[1] - v[0], v[2] - v[0])
        t = np.array([np.cos(road.heading(s)), np.sin(road.heading(s)), 0.0]) * facing
        out.add(CONCRETE, Shape(v, QUAD if n @ t > 0 else QUAD[:, [0, 2, 1]]))
    out.clear.append(_quad_polygon(road, a - 0.5, b + 0.5, d0, d1))


def _frontage_ground(road: RoadLayout, plan: Frontage, ground: Material, out: _Meshes) -> None:
    """Asphalt, the cross street, sidewalks and curbs broken by side streets, and each lot's
    ground (car parks paved at sidewalk height) out to LAND_DEPTH."""
    ch, sw = road.curb_height, road.sidewalk_width
    carriageway(road, out)
    if road.cross_s is not None:
        out.clear.append(cross_street(road, out.add, LAND_DEPTH + sw))
    for side in (-1, 1):
        curb, outer = (road.right_curb if side < 0 else road.left_curb), _outer(road, side)
        lo, hi = sorted((curb, outer))
        spans = _spans(road, 0.0)
        for a, b in plan.mouths[side]:
            spans = cut(spans, a, b)
            _side_street(road, side, a, b, out)
        for s0, s1 in spans:
            ss = road.samples(s0, s1)
            out.add(SIDEWALK, strip(road, ss, lo, hi, ch))
            face = strip(road, ss, curb, curb, 0.0, ch)
            out.add(CONCRETE, face if side < 0 else flip(face))
    for lot in plan.lots:
        s0, s1 = max(lot.s0, road.s_min), min(lot.s1, road.s_max)
        if s1 <= s0:
            continue
        ss, outer = road.samples(s0, s1), _outer(road, lot.side)
        q = 0.0
        if lot.depth > 0:  # car park paving
            out.add(ASPHALT, strip(road, ss, *sorted((outer, outer + lot.side * lot.depth)), ch))
            q = lot.depth
        out.add(ground, strip(road, ss, *sorted((outer + lot.side * q, outer + lot.side * LAND_DEPTH)), ch))


def _street_trees(road: RoadLayout, side: int, per_100m: float, rng: np.random.Generator,
                  out: _Meshes) -> None:
    """Street trees on the sidewalk, sized as GALK's street trees; crowns reaching over the
    carriageway start at 4.5 m, others at 2.5 m."""
    ch, sw = road.curb_height, road.sidewalk_width
    curb = road.right_curb if side < 0 else road.left_curb
    inset = min(1.0, sw / 2)
    d = _outer(road, side) - side * inset
    st = np.sort(rng.uniform(road.s_min, road.s_max, rng.poisson(per_100m * (road.s_max - road.s_min) / 100.0)))
    h, r, base = (np.empty(len(st)) for _ in range(3))
    for i in range(len(st)):  # the crown base is drawn only for crowns clear of the carriageway
        h[i], r[i] = rng.uniform(*TREE_HEIGHT), rng.uniform(*CROWN_RADIUS)
        base[i] = CLEAR_ROAD if r[i] > abs(d - curb) else rng.uniform(CLEAR_FOOTWAY, CLEAR_ROAD)
    _trees(out, road.xy(st, d), ch, h, r, base, 0.2)


def build_frontage(road: RoadLayout, plan: Frontage, clutter: dict, ground: Material,
                   seed: int, out: _Meshes) -> None:
    """The frontage world: ground, lots, street trees, poles (own random streams per part)."""
    _frontage_ground(road, plan, ground, out)
    markings(road, out)
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
            poles(road, side, road.right_curb if side < 0 else road.left_curb,
                  clutter["pole_spacing"], rng, out)
