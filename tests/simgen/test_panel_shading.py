"""Curved-panel shading of actors (simgen.render._bent_normals) against hand-computed normals."""

from __future__ import annotations

import numpy as np

from simgen.facets import triangles
from simgen.meshes import box
from simgen.render import BEND, PANEL_TURN, _bent_normals
from simgen.world import Material, Part


def _part(x0, x1, y0, y1, z0, z1) -> Part:
    return Part(box(x0, x1, y0, y1, z0, z1), Material("paint", (0.5, 0.5, 0.5), 0.3))


def test_a_box_face_turns_through_the_panel_turn_between_opposite_edges():
    parts = [_part(-2.0, 2.0, -0.9, 0.9, 0.2, 1.4)]  # a car-sized slab, off the origin in z
    tris, normals = triangles(parts)
    bent = _bent_normals([12], tris, normals)
    side = np.flatnonzero(normals[:, 1] > 0.99)  # the +y face (a door's side)
    assert len(side) == 2
    for f in side:
        for corner, n in zip(tris[f], bent[f]):
            # Each corner of the face sits at (+-1, 1, +-1) half extents from the box's centre.
            d = np.sign(corner - [0.0, 0.0, 0.8])
            expected = np.array([0.0, 1.0, 0.0]) + BEND * d
            np.testing.assert_allclose(n, expected / np.linalg.norm(expected), atol=1e-12)
            # In the face's cross-section (y, z) the corner's normal leans by half the turn.
            assert abs(np.arctan2(abs(n[2]), n[1]) - PANEL_TURN / 2) < 1e-12
    assert np.all(np.einsum("fkj,fj->fk", bent, normals) > 0.8)  # never turned away from the face


def test_each_part_bends_about_its_own_box():
    """Two parts of one actor: the same face of each has the same corner normals, wherever the
    part sits and however large it is (half extents, not metres)."""
    a, b = _part(0.0, 1.0, 0.0, 1.0, 0.0, 1.0), _part(5.0, 9.0, -3.0, 1.0, 2.0, 2.5)
    tris, normals = triangles([a, b])
    bent = _bent_normals([12, 12], tris, normals)
    na = len(a.mesh.faces)
    np.testing.assert_allclose(bent[:na], bent[na:], atol=1e-12)
