"""Textures on actors (simgen.textures glass, paint and plate tiles; simgen.render
_actor_primitives): what the tiles hold, texture coordinates by hand, and that a texture changes
a car's colour only, never its depth or its instance mask."""

from __future__ import annotations

import dataclasses

import numpy as np
import pyrender
import pytest

from simgen import textures
from simgen.facets import triangles
from simgen.materials import GLASS, PLATE, TRIM
from simgen.meshes import box, paint
from simgen.render import _texture_coordinates, _View, build_scene, render
from simgen.sample import sample_world
from simgen.spec import load_spec
from simgen.world import Part


def _multipliers(kind: str) -> np.ndarray:
    return textures.tile(kind, 0).astype(np.float64) * textures.MAX_GAIN / 255.0


@pytest.mark.parametrize("kind", sorted(textures.ACTOR_MAKERS))
def test_actor_tiles_keep_the_material_colour_on_average(kind):
    np.testing.assert_allclose(_multipliers(kind).reshape(-1, 3).mean(axis=0), 1.0, atol=0.01)


@pytest.mark.parametrize("kind", ["glass", "paint"])
def test_glass_and_paint_repeat_along_the_car_without_a_seam(kind):
    grey = _multipliers(kind).mean(axis=2)
    inner = np.abs(np.diff(grey, axis=1)).mean(axis=0).max()
    assert np.abs(grey[:, 0] - grey[:, -1]).mean() <= inner


def test_glass_shows_seats_dark_against_the_view_through():
    grey = _multipliers("glass").mean(axis=2)
    rows = lambda a, b: slice(int(a * textures.SIZE), int(b * textures.SIZE))  # noqa: E731
    pitch = textures.GLASS_TILE_M / round(textures.GLASS_TILE_M / textures.HEADREST_PITCH)
    seat_col = int(pitch / 2 / textures.GLASS_TILE_M * textures.SIZE)  # a seat's centre line
    gap_col = 0  # halfway between two seats
    through = np.median(grey[rows(0.3, 0.45), gap_col])
    restraint = np.median(grey[rows(0.3, 0.42), seat_col])
    trim = np.median(grey[rows(0.7, 1.0)])
    assert restraint < 0.5 * through and trim < 0.6 * through
    # The mirrored sky at the top is lighter than the trim, darker than the view through.
    assert trim < np.median(grey[rows(0.0, 0.2)]) < through


def test_plates_are_white_with_dark_characters_and_a_blue_band():
    m = _multipliers("plate")
    band = textures.SIZE // textures.PLATES_PER_TILE
    for k in range(textures.PLATES_PER_TILE):
        plate = m[k * band:(k + 1) * band]
        grey = plate.mean(axis=2)
        dark = grey < 0.3 * np.median(grey)
        assert 0.05 < dark.mean() < 0.4  # rim and characters, not most of the plate
        blue = plate[band // 2, 5]
        assert blue[2] > 3 * blue[0]  # the EU band
    assert not np.array_equal(m[:band], m[band:2 * band])  # each plate its own characters


def _actor() -> list[Part]:
    """A pane, a body panel, a rear plate and a black bumper (actor frame, metres)."""
    return [Part(box(-1.0, 1.0, -0.7, 0.7, 1.0, 1.4), GLASS),
            Part(box(-2.0, 2.0, -0.9, 0.9, 0.3, 1.0), paint((0.5, 0.1, 0.1))),
            Part(box(-2.01, -2.0, -0.26, 0.26, 0.5, 0.61), PLATE),
            Part(box(-2.1, -2.0, -0.9, 0.9, 0.2, 0.45), TRIM)]


def test_texture_coordinates_by_hand():
    parts = _actor()
    tris, normals = triangles(parts)
    shift, plate = 0.37, 2
    worn = _texture_coordinates(parts, tris, normals, np.full(len(tris), shift), np.full(len(tris), plate))
    # Each textured part's faces, in order; the black bumper wears none.
    assert sorted(worn) == ["glass", "paint", "plate"]
    for k, kind in enumerate(("glass", "paint", "plate")):
        np.testing.assert_array_equal(worn[kind][0], np.arange(12 * k, 12 * k + 12))
    # Glass: along the car in tiles (across it on the end faces), up the pane from 0 to 1.
    t, n = tris[:12], normals[:12]
    along = np.where((np.abs(n[:, 1]) >= np.abs(n[:, 0]))[:, None], t[..., 0], t[..., 1])
    np.testing.assert_allclose(worn["glass"][1][..., 0], along / textures.GLASS_TILE_M + shift, atol=1e-12)
    np.testing.assert_allclose(worn["glass"][1][..., 1], (t[..., 2] - 1.0) / 0.4, atol=1e-12)
    # Paint: metres over the tile size, along and up the side, along and across the top.
    t, n = tris[12:24], normals[12:24]
    up = (np.abs(n[:, 2]) >= 0.7)[:, None]
    side = (np.abs(n[:, 1]) >= np.abs(n[:, 0]))[:, None]
    tu, tv = textures.PAINT_TILE_M
    np.testing.assert_allclose(worn["paint"][1][..., 0], np.where(up | side, t[..., 0], t[..., 1]) / tu + shift,
                               atol=1e-12)
    np.testing.assert_allclose(worn["paint"][1][..., 1], np.where(up, t[..., 1], t[..., 2]) / tv + shift,
                               atol=1e-12)
    # The rear plate's face (normal -x), seen from behind: u runs from +y (its left) to -y.
    rear = np.flatnonzero(normals[24:36, 0] < -0.99)
    assert len(rear) == 2
    t = tris[24:36][rear]
    uv = worn["plate"][1][rear]
    np.testing.assert_allclose(uv[..., 0], (0.26 - t[..., 1]) / 0.52, atol=1e-9)
    np.testing.assert_allclose(uv[..., 1], ((t[..., 2] - 0.5) / 0.11 + plate) / textures.PLATES_PER_TILE,
                               atol=1e-9)


def test_the_colour_pass_draws_every_actor_face_in_view_once_textured_faces_as_stored():
    """All actors in one mesh: a primitive per texture and one plain, every face of every actor
    that may reach a pixel (render._View) in exactly one, the textured ones' colours scaled by
    MAX_GAIN as the tiles are; the instance pass draws the same faces, actor by actor."""
    world = sample_world(load_spec("scenes/urban.yaml"), 0, 0)
    built = build_scene(world)
    rig = world.rig
    view = _View.of(rig.intrinsics(), rig.cam2_from_world(), rig.width, rig.height)
    seen = []  # faces in view, per actor
    for a in world.actors:
        for p in a.parts:
            v = np.asarray(p.mesh.vertices) @ a.pose[:3, :3].T + a.pose[:3, 3]
            seen.append(int(view.faces(v, np.asarray(p.mesh.faces)).sum()))
    faces = sum(len(p.mesh.faces) for a in world.actors for p in a.parts)
    assert 0 < sum(seen) < faces / 2  # most of the street lies beside and behind the camera
    prims = built.layers[-1].node.mesh.primitives  # static world, sky dome, the actors
    assert [p.material.baseColorTexture is None for p in prims] == [False, False, False, True]
    assert sum(len(p.positions) for p in prims) == 3 * sum(seen)
    assert all(np.max(p.color_0[:, :3]) > 1.0 for p in prims[:3]) and np.max(prims[3].color_0) <= 1.0
    own = [len(i.draw.tris) for i in built.instances if i.actor]
    assert sum(own) == sum(seen) and min(own) > 0


def test_textures_change_a_cars_colour_only():
    """The same world with and without textures: depth and instance maps byte for byte, the
    colour of the actors' pixels changed and their texture visible (more contrast)."""
    world = sample_world(load_spec("scenes/urban.yaml"), 0, 0)
    plain = dataclasses.replace(world, appearance=dataclasses.replace(world.appearance, textures=False))
    a, b = render(world), render(plain)
    assert np.array_equal(a.depth, b.depth) and np.array_equal(a.instance, b.instance)
    cars = a.instance > 0
    assert cars.sum() > 1000
    grey_a, grey_b = a.color.mean(axis=2)[cars], b.color.mean(axis=2)[cars]
    assert not np.array_equal(grey_a, grey_b)
    assert np.std(grey_a) > np.std(grey_b)


def test_the_colour_pass_draws_its_nodes_in_one_order():
    """pyrender draws the nodes farthest from the camera first and nodes at one distance in the
    order of a set, which changes run by run; where two nodes' surfaces meet at one depth (a
    tyre on the road) the order decides the pixel. So no two nodes the colour pass draws may
    stand at one distance, and the same world renders to the same bytes twice."""
    world = sample_world(load_spec("scenes/urban.yaml"), 0, 53)  # a frame where the order showed
    built = build_scene(world)
    scene = built.scene
    cam = scene.get_pose(scene.main_camera_node)[:3, 3]
    far = [float(np.linalg.norm(scene.get_pose(n)[:3, 3] - cam)) for n in scene.mesh_nodes]
    assert len(far) == 3 and len(set(far)) == 3  # static world, sky dome, the actors
    a, b = render(world), render(world)
    assert np.array_equal(a.color, b.color)


def test_nodes_at_one_distance_are_drawn_in_the_order_they_were_added():
    """An orbit view's target car stands at the origin with the static world, whose road its tyres
    touch at one depth; at night each lamp stands at its vehicle's distance. pyrender keeps the
    scene's order among nodes at one distance, and in a plain set that order changed from run to
    run (frame 6 of variations.yaml, a night orbit view: a lamp's pixels differed between two
    runs). The scene's nodes now iterate in the order they were added, lights too."""
    world = sample_world(load_spec("scenes/variations.yaml"), 0, 6)
    built = build_scene(world)
    scene = built.scene
    cam = scene.get_pose(scene.main_camera_node)[:3, 3]
    far = [float(np.linalg.norm(scene.get_pose(n)[:3, 3] - cam)) for n in scene.mesh_nodes]
    assert len(set(far)) < len(far)  # ties are there: the order among them matters
    nodes = list(scene.mesh_nodes)
    assert nodes[0].mesh is not None and len(nodes) == len(scene.mesh_nodes)
    # The instance pass draws the same nodes (no sky dome at night), listed in the order added.
    assert [i.draw.pose.tolist() for i in built.instances] == [n.matrix.tolist() for n in nodes]
    added = [scene.add(pyrender.Mesh([n.mesh.primitives[0]])) for n in nodes[1:41]]
    assert list(scene.mesh_nodes)[-len(added):] == added
    assert [type(n.light).__name__ for n in scene.light_nodes] == ["SpotLight", "SpotLight", "DirectionalLight"]
    cam_from_scene = np.linalg.inv(scene.get_pose(scene.main_camera_node))
    assert [round(float((cam_from_scene @ scene.get_pose(n))[0, 3]), 6) for n in scene.spot_light_nodes] == [-0.6, 0.6]
