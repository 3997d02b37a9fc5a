"""The colour and instance passes leave out the faces the camera cannot see (simgen.render._View):
the view volume's planes against pixels computed by hand, and whole frames rendered with and
without the culling, byte for byte."""

from __future__ import annotations

import numpy as np
import pytest

from simgen import render as R
from simgen.sample import sample_world
from simgen.spec import load_spec

W = H = 101  # a 101 x 101 image, f = 100 px, centred; the camera at the origin looking along +z
K = np.array([[100.0, 0.0, 50.0], [0.0, 100.0, 50.0], [0.0, 0.0, 1.0]])


def _tri(*corners) -> np.ndarray:
    return np.array(corners, float)


def test_the_view_volume_by_hand():
    """A pixel centre at u lies at x = (u - 50) z / 100: the image's right edge (u = 100.5) at
    z = 10 m is x = 5.05 m, two pixels beyond it x = 5.25 m; the near plane stands at ZNEAR."""
    view = R._View.of(K, np.eye(4), W, H)
    tris = {
        "in view": (_tri([0, 0, 10], [1, 0, 10], [0, 1, 10]), True),
        "behind the camera": (_tri([0, 0, -5], [1, 0, -5], [0, 1, -1]), False),
        "in front of the near plane only": (_tri([0, 0, 0.29], [0.01, 0, 0.29], [0, 0.01, 0.29]), False),
        "across the near plane": (_tri([0, 0, -1], [0.1, 0, 1], [0, 0.1, 1]), True),
        "2.5 px beyond the right edge and more": (_tri([5.3, 0, 10], [6, 0, 10], [6, 1, 10]), False),
        "1.5 px beyond the right edge": (_tri([5.2, 0, 10], [6, 0, 10], [6, 1, 10]), True),
        "2.5 px above the top edge and more": (_tri([0, -5.3, 10], [1, -6, 10], [0, -7, 10]), False),
        "corners outside three different sides": (_tri([-20, 20, 10], [20, 20, 10], [0, -20, 10]), True),
    }
    vertices = np.concatenate([t for t, _ in tris.values()])
    faces = np.arange(len(vertices)).reshape(-1, 3)
    got = view.faces(vertices, faces)
    assert dict(zip(tris, got.tolist())) == {k: want for k, (_, want) in tris.items()}
    # Moving the world moves the planes with it: the same triangles seen by a camera 3 m to the
    # right (world x) keep their answers when the triangles move 3 m too.
    moved = R._View.of(K, np.array([[1.0, 0, 0, -3.0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), W, H)
    assert np.array_equal(moved.faces(vertices + [3.0, 0.0, 0.0], faces), got)


@pytest.mark.parametrize("spec, frame, mode", [("scenes/urban.yaml", 0, "lit"),
                                               ("scenes/variations.yaml", 14, "pbr"),
                                               ("scenes/variations.yaml", 0, "thermal")])
def test_culling_leaves_every_pixel_as_it_was(spec, frame, mode, monkeypatch):
    """The same world rendered with the culling and with every face drawn: colour, depth and
    instance maps byte for byte, while the instance pass left out at least every static face behind
    the camera (over a tenth of the faces on urban.yaml's onboard camera, whose world reaches all
    round it)."""
    spec = load_spec(spec)
    world = sample_world(spec, spec.seed, frame)
    assert R._Shader(world, np.zeros(3)).mode == mode
    total = sum(len(p.mesh.faces) for p in world.static) + sum(
        len(p.mesh.faces) for a in world.actors for p in a.parts)
    built = R.build_scene(world)
    drawn = sum(len(i.draw.tris) for i in built.instances)  # the instance pass
    culled = R.render(world)
    monkeypatch.setattr(R._View, "faces", lambda self, vertices, faces: np.ones(len(faces), bool))
    whole = R.render(world)
    for a, b in ((culled.color, whole.color), (culled.depth, whole.depth), (culled.instance, whole.instance)):
        assert np.array_equal(a, b)
    # every static face wholly behind the near plane is left out; on urban.yaml a fifth of the
    # street (s from -40 to 160 m, the camera at 0) lies behind the camera
    cam = world.rig.cam2_from_world()
    behind = 0
    for p in world.static:
        z = p.mesh.vertices @ cam[2, :3] + cam[2, 3]
        behind += int((z[p.mesh.faces] < R.ZNEAR).all(axis=1).sum())
    if mode == "lit":
        assert behind > total / 10
    assert drawn <= total - behind
