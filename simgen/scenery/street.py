"""The first street model: carriageway, ground, lane markings, and along each side a closed row of
buildings (or a fence), trees and poles. The frontage world (simgen.scenery.lots) lays the same
carriageway and markings and stands the same poles."""

from __future__ import annotations

import numpy as np
import trimesh

from ..materials import ASPHALT, BARK, CONCRETE, FACADE_REFLECTIVITY, FENCE, FOLIAGE, MARKING, METAL, SIDEWALK
from ..road import RoadLayout
from ..world import Material
from .parts import (FACADES, MARK_Z, Obstacle, VERGE_WIDTH, _Meshes, _spans, cross_street, flip, footprint,
                    moved, oriented_box, plain, strip)


def carriageway(road: RoadLayout, out: _Meshes) -> None:
    """The asphalt from curb to curb; a crowned one in two strips that meet at the crown (the
    divider), so that the draped surface bends there and not across a triangle."""
    ss = road.samples(road.s_min, road.s_max)
    if road.crown == 0.0:
        out.add(ASPHALT, strip(road, ss, road.right_curb, road.left_curb, 0.0))
        return
    out.add(ASPHALT, strip(road, ss, road.right_curb, road.divider, 0.0))
    out.add(ASPHALT, strip(road, ss, road.divider, road.left_curb, 0.0))


def _ground(road: RoadLayout, ground: Material, out: _Meshes) -> None:
    """Asphalt, the cross street, sidewalks, curb faces and the verges beyond them."""
    carriageway(road, out)
    if road.cross_s is not None:
        out.clear.append(cross_street(road, out.add))
    ch, sw = road.curb_height, road.sidewalk_width
    for side in (-1, 1):
        curb = road.right_curb if side < 0 else road.left_curb
        outer = curb + side * sw
        lo, hi = sorted((curb, outer))
        for s0, s1 in _spans(road, 0.0):
            ss = road.samples(s0, s1)
            out.add(SIDEWALK, strip(road, ss, lo, hi, ch))
            face = strip(road, ss, curb, curb, 0.0, ch)
            out.add(CONCRETE, face if side < 0 else flip(face))
        vlo, vhi = sorted((outer, outer + side * VERGE_WIDTH))
        for s0, s1 in _spans(road, sw):
            out.add(ground, strip(road, road.samples(s0, s1), vlo, vhi, ch))


def markings(road: RoadLayout, out: _Meshes) -> None:
    """Solid edge lines and divider, dashed lines between lanes of one direction."""
    w = 0.15
    spans = _spans(road, 0.0)
    for s0, s1 in spans:
        ss = road.samples(s0, s1)
        for d in (road.right_lane_edge + 0.25, road.left_lane_edge - 0.25):
            out.add(MARKING, strip(road, ss, d - w / 2, d + w / 2, MARK_Z))
        for off in (-0.12, 0.12):
            out.add(MARKING, strip(road, ss, road.divider + off - w / 2, road.divider + off + w / 2, MARK_Z))
    dash, gap = 3.0, 9.0
    starts = np.arange(np.floor(road.s_min / (dash + gap)) * (dash + gap), road.s_max, dash + gap)
    for k in range(1, road.lanes):
        for base in (road.right_lane_edge, road.left_lane_edge):
            d = base + k * road.lane_width if base == road.right_lane_edge else base - k * road.lane_width
            for s0 in starts:
                for lo_s, hi_s in spans:
                    ss = road.samples(max(s0, lo_s), min(s0 + dash, hi_s), 1.0)
                    if ss[-1] > ss[0]:
                        out.add(MARKING, strip(road, ss, d - w / 2, d + w / 2, MARK_Z))


def _buildings(road: RoadLayout, side: int, outer: float, setback: float, rng: np.random.Generator,
               out: _Meshes) -> None:
    """A row of boxes behind the sidewalk, gaps between some; one drawn but blocked is skipped."""
    sb = road.s_min - 10.0
    while sb < road.s_max + 10.0:
        length = rng.uniform(8.0, 30.0)
        depth, height = rng.uniform(8.0, 16.0), rng.uniform(5.0, 20.0)
        d = outer + side * (setback + depth / 2)
        m = oriented_box(road, sb + length / 2, d, road.curb_height, length, depth, height)
        sb += length + rng.choice([0.0, rng.uniform(2.0, 10.0)])
        fp = footprint(m)
        if out.blocked(fp):
            continue
        out.add(Material("facade", FACADES[int(rng.integers(len(FACADES)))], FACADE_REFLECTIVITY), m)
        out.obstacles.append(Obstacle(fp))


def fences(road: RoadLayout, side: int, outer: float, out: _Meshes) -> None:
    """A 1.2 m fence along the sidewalk's outer edge, broken by the cross street."""
    ch = road.curb_height
    for s0, s1 in _spans(road, road.sidewalk_width):
        m = strip(road, road.samples(s0, s1), outer - side * 0.3, outer - side * 0.3, ch, ch + 1.2)
        out.add(FENCE, m if side < 0 else flip(m))


def trees(road: RoadLayout, side: int, outer: float, per_100m: float, woods: float,
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
        out.obstacles.append(Obstacle(footprint(trunk).buffer(0.1)))
        out.obstacles.append(Obstacle(footprint(crown), base=ch + trunk_h))


_POLE = plain(trimesh.creation.cylinder(radius=0.09, height=7.0, sections=8))  # moved to each pole's place


def poles(road: RoadLayout, side: int, curb: float, spacing: float, rng: np.random.Generator,
          out: _Meshes) -> None:
    """7 m poles half a metre behind the curb, evenly spaced from a random start."""
    ch = road.curb_height
    for sp in np.arange(road.s_min + rng.uniform(0, spacing), road.s_max, spacing):
        x, y = road.xy(sp, curb + side * 0.5)
        pole = moved(_POLE, [x, y, ch + 3.5])
        fp = footprint(pole)
        if out.blocked(fp):
            continue
        out.add(METAL, pole)
        out.obstacles.append(Obstacle(fp.buffer(0.1)))
