"""Sun shadows (simgen.shadows) against the exact shadow of a box on the ground."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from simgen import facets
from simgen.embree import EMBREE_CONFIG, embree_scene
from simgen.materials import ASPHALT, FOLIAGE
from simgen.meshes import box
from simgen.shadows import (SKY_RAYS, SKY_STEP, SOFTEN, STEP, Occluders, Reach, SplitCasters,
                            WorldScene, sky_directions, sky_occlusion, sun_shadow)
from simgen.world import Material, Part

F, N = 100.0, 101  # a 101 x 101 camera 20 m above the ground, looking straight down
K = np.array([[F, 0.0, 50.0], [0.0, F, 50.0], [0.0, 0.0, 1.0]])
CAM2_FROM_WORLD = np.array([[1.0, 0, 0, 0], [0, -1.0, 0, 0], [0, 0, -1.0, 20.0], [0, 0, 0, 1.0]])


def _casters(material: Material) -> Occluders:
    """A ground square and a floating box (world frame)."""
    ground = trimesh.Trimesh([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]],
                             [[0, 1, 2], [0, 2, 3]], process=False)
    parts = [Part(ground, ASPHALT), Part(box(-2, 2, -2, 2, 5, 6), material)]
    return Occluders.of_mesh(parts, *facets.shared(parts))


def _pixels_of(x0: float, x1: float, y0: float, y1: float) -> tuple[slice, slice]:
    """Rows and columns of ground pixels over a rectangle (u = 50 + 5 x, v = 50 - 5 y)."""
    return (slice(max(0, int(50 - 5 * y1)), int(50 - 5 * y0) + 1),
            slice(max(0, int(50 + 5 * x0)), int(50 + 5 * x1) + 1))


@pytest.mark.parametrize("material, depth", [(Material("slab", (0.5, 0.5, 0.5), 0.3), 1.0),
                                             (FOLIAGE, 1.0 - FOLIAGE.porosity ** 2)])
def test_a_box_casts_its_exact_shadow_and_leaves_let_light_through(material, depth):
    depth_img = np.full((N, N), 20.0, np.float32)
    depth_img[:3] = 0.0  # a strip of sky
    to_sun = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)  # 45 deg above the +x horizon
    shade = sun_shadow(_casters(material), depth_img, K, CAM2_FROM_WORLD, to_sun)
    # A ground point p is shaded when p + z (1, 0, 1) meets the box for z in [5, 6]:
    # x in [-2 - z, 2 - z], so x in [-8, -3], and y in [-2, 2].
    # Metres (5 pixels a metre): the ray grid, its softening (3 sd) and bilinear upsampling.
    margin = STEP * (1 + 3 * SOFTEN) / 5.0 + 0.2
    inside = _pixels_of(-8 + margin, -3 - margin, -2 + margin, 2 - margin)
    assert np.allclose(shade[inside], depth, atol=0.01)  # the softening reaches 1 % inside
    outside = np.ones((N, N), bool)
    outside[_pixels_of(-8 - margin, -3 + margin, -2 - margin, 2 + margin)] = False
    assert np.all(shade[outside] < 0.005)  # the softening's tail beyond 3 sd
    assert np.all(shade[:3] == 0.0)  # the sky


def test_no_shadow_with_the_sun_below_the_horizon_or_only_where_asked():
    depth_img = np.full((N, N), 20.0, np.float32)
    world = _casters(Material("slab", (0.5, 0.5, 0.5), 0.3))
    assert not sun_shadow(world, depth_img, K, CAM2_FROM_WORLD, np.array([1.0, 0.0, -0.1])).any()
    sunlit = np.zeros((N, N), bool)  # no pixel faces the sun: no ray is cast
    assert not sun_shadow(world, depth_img, K, CAM2_FROM_WORLD, np.array([0.0, 0.0, 1.0]), sunlit).any()


def test_the_lidars_scene_of_the_world_casts_the_same_shadows():
    """The static world from another sensor's scene, whose actors stand elsewhere (a box moved
    1.5 m: rays that meet it there and not here find the ground behind it), and the camera's
    actors from their own: bit for bit the shadow of one scene of both."""
    depth_img = np.full((N, N), 20.0, np.float32)
    to_sun = np.array([1.0, 0.3, 1.2]) / np.linalg.norm([1.0, 0.3, 1.2])
    static = _casters(FOLIAGE)  # the ground and a crown
    actor = [Part(box(-6, -4, 1, 3, 1, 2.5), Material("slab", (0.5, 0.5, 0.5), 0.3))]
    actors = Occluders.of_mesh(actor, *facets.shared(actor))
    elsewhere = Occluders(actors.vertices + np.float32([1.5, 0.0, 0.0]), actors.faces, actors.depth)
    world = Occluders.join(static, elsewhere)
    split = SplitCasters(WorldScene(world.scene(), len(static.faces)), static, actors)
    one = sun_shadow(Occluders.join(static, actors), depth_img, K, CAM2_FROM_WORLD, to_sun)
    assert one.any()
    assert np.array_equal(sun_shadow(split, depth_img, K, CAM2_FROM_WORLD, to_sun), one)


def _corner_factor(a: float, b: float, c: float) -> float:
    """Cosine-weighted view factor from a horizontal surface element to a parallel a x b
    rectangle c above it, one corner over the element (Howell's catalogue of view factors: a plane
    element to a parallel rectangle, its normal through a corner)."""
    x, y = a / c, b / c
    return (x / np.hypot(1, x) * np.arctan(y / np.hypot(1, x))
            + y / np.hypot(1, y) * np.arctan(x / np.hypot(1, y))) / (2 * np.pi)


def _plate_factor(px: float, py: float, half: float, c: float) -> float:
    """The same to a 2 half x 2 half plate centred over the origin, from the point (px, py): the
    signed sum of the four rectangles between the point and the plate's corners."""
    def signed(a: float, b: float) -> float:
        return np.sign(a) * np.sign(b) * _corner_factor(abs(a), abs(b), c)

    x1, x0, y1, y0 = half - px, -half - px, half - py, -half - py
    return signed(x1, y1) - signed(x0, y1) - signed(x1, y0) + signed(x0, y0)


def test_sky_occlusion_of_a_plate_is_its_view_factor():
    """Ground points under and beside a thin plate 1 m up lose the share of the sky the plate
    covers (the exact view factor), up to the 32-ray quadrature; none beyond the reach, none off
    the ground mask."""
    half, c = 2.0, 1.0
    plate = Part(box(-half, half, -half, half, c, c + 0.01), Material("slab", (0.5, 0.5, 0.5), 0.3))
    occ = Occluders.of_mesh([plate], *facets.shared([plate]))
    # The reach's box stands on the ground, as an actor's does.
    reach = Reach(np.eye(4)[None], np.array([[-half, -half, 0.0]]), np.array([[half, half, c + 0.01]]))
    depth_img = np.full((N, N), 20.0, np.float32)
    ground = np.ones((N, N), bool)
    ground[:, :10] = False
    got = sky_occlusion(occ, reach, depth_img, ground, K, CAM2_FROM_WORLD)
    # Ground pixel (u, v) lies at x = (u - 50) / 5, y = (50 - v) / 5; the ray grid's points
    # within the reach (2 m 2 cm beyond the plate's edges) against the view factor. The 32-ray
    # quadrature of a step-edged plate errs by 0.02 on average and under 0.09 anywhere (the
    # same rays against the formula over a 0.1 m lattice of points).
    errors = []
    for u in range(SKY_STEP // 2 + SKY_STEP, 90, SKY_STEP):
        for v in range(SKY_STEP // 2 + SKY_STEP, 90, SKY_STEP):
            x, y = (u - 50) / 5.0, (50 - v) / 5.0
            errors.append(got[v, u] - _plate_factor(x, y, half, c - 0.05))
    errors = np.abs(errors)
    assert errors.mean() < 0.025 and errors.max() < 0.09
    assert got[51, 51] > 0.75  # under the middle of the plate: 0.83 of the sky hidden
    assert not got[:, :10].any()  # not ground
    # Beyond the reach (|x| or |y| > 4.02 m) and one grid step of interpolation: nothing.
    assert not got[:, 77:].any() and not got[:24].any() and not got[77:].any()
    assert sky_directions().shape == (SKY_RAYS, 3)
    assert np.allclose(np.linalg.norm(sky_directions(), axis=1), 1.0)


def test_darken_by_hand():
    """Linear light: a quarter of it from the sky (alpha encodes 0.25 ** (1 / 2.2)), untinted.
    Full shadow leaves that quarter, 200 * 0.25 ** (1 / 2.2) = 106.5; shadow and full sky
    occlusion leave nothing; half the sky hidden in the sun leaves 1 - 0.125, 200 * 0.875 **
    (1 / 2.2) = 188.2; nothing darkened leaves the colour."""
    from simgen.render import darken

    alpha = np.full(4, int(round(255 * 0.25 ** (1 / 2.2))), np.int64)  # 136: 0.2506 linear
    rest = (alpha[0] / 255.0) ** 2.2
    got = darken(np.full((4, 3), 200, np.uint8), alpha, np.array([1.0, 1.0, 0.0, 0.0], np.float32),
                 np.array([0.0, 1.0, 0.5, 0.0], np.float32), np.ones(3, np.float32))
    expected = np.round(200 * np.array([rest, 0.0, 1 - 0.5 * rest, 1.0]) ** (1 / 2.2))
    assert np.array_equal(got, np.repeat(expected[:, None], 3, axis=1))
    assert list(expected) == [107.0, 0.0, 188.0, 200.0]


def test_darken_is_numpys_float32_arithmetic_pixel_by_pixel():
    """The compiled loop against numpy's operators one after another (the arithmetic the frames'
    bytes were first made with) on a million random pixels, shadow and occlusion at every depth."""
    from simgen.render import _LINEAR, darken

    rng = np.random.default_rng(0)
    n = 1_000_000
    rgb = rng.integers(0, 256, (n, 3)).astype(np.uint8)
    alpha = rng.integers(0, 256, n)
    sun = (rng.random(n) * (rng.random(n) < 0.7)).astype(np.float32)
    sky = (rng.random(n) * (rng.random(n) < 0.5)).astype(np.float32)
    tint = np.array([0.8, 0.95, 1.3], np.float32)
    r = np.take(np.minimum(_LINEAR[:, None] * tint, np.float32(1.0)), alpha, axis=0)
    left = (1.0 - sun[:, None]) * (1.0 - r) + (1.0 - sky[:, None]) * r
    want = np.clip(np.round(rgb * np.power(left, np.float32(1 / 2.2))), 0, 255).astype(np.uint8)
    assert np.array_equal(darken(rgb, alpha, sun, sky, tint), want)


def test_along_keeps_what_a_ray_may_meet():
    """Occluders.along by hand: rays from two points straight up (and a slanted sun) can meet
    only what stands in their prism, above the lower point; with and without shared vertices."""
    tri = {"above": [[0, 0, 5], [1, 0, 5], [0, 1, 5]],
           "far above": [[0.5, 0.5, 1000], [2, 0.5, 1000], [0.5, 2, 1000]],
           "across the prism, corners outside": [[-5, 0.5, 5], [5, 0.5, 5], [5, 0.6, 5]],
           "beside it, 4 cm off": [[1.04, 0, 5], [2, 0, 5], [2, 1, 5]],
           "beside it, 1 m off": [[2, 0, 5], [3, 0, 5], [3, 1, 5]],
           "below the points": [[0, 0, -1], [1, 0, -1], [0, 1, -1]]}
    want = [True, True, True, True, False, False]
    tris = np.array(list(tri.values()), np.float32)
    depth = np.linspace(0.1, 0.6, len(tris)).astype(np.float32)
    points = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    up = np.array([0.0, 0.0, 1.0])
    faces = np.arange(3 * len(tris), dtype=np.int32).reshape(-1, 3)
    shared = Occluders(tris.reshape(-1, 3), faces, depth)
    for occ in (Occluders.of_triangles(tris, depth), shared):
        kept = occ.along(points, up)
        assert np.array_equal(kept.depth, depth[want])  # the kept triangles, in their order
        assert np.array_equal(kept.tris, tris[want])
    # A sun 45 deg above +x: a point's rays run through (5, 0, 5) and never below z = -x.
    slant = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    on_it = np.array([[[5, -0.1, 5], [5.1, 0.1, 5], [4.9, 0.1, 5]], [[0, -1, -5], [1, 1, -5], [-1, 1, -5]]],
                     np.float32)
    kept = Occluders.of_triangles(on_it, np.ones(2, np.float32)).along(np.zeros((1, 3)), slant)
    assert np.array_equal(kept.tris, on_it[:1])


def test_leaving_out_what_no_ray_meets_changes_no_shadow(monkeypatch):
    """A street frame's shade with the casters cut to the rays' prism and with all of them:
    the same bytes."""
    from simgen import render
    from simgen.sample import sample_world
    from simgen.spec import load_spec

    world = sample_world(load_spec("scenes/urban.yaml"), 0, 3)
    cut = render.render(world).color
    monkeypatch.setattr(Occluders, "along", lambda self, points, direction: self)
    assert np.array_equal(cut, render.render(world).color)


def test_embree_runs_the_same_kernels_on_every_cpu_from_avx2_up():
    """Embree's kernels of different widths put the same hits a few ulps apart; every scene is
    made on a device capped at AVX2, so an AVX-512 machine writes the bytes an AVX2 one does."""
    rng = np.random.default_rng(0)
    tri = (rng.uniform(-5, 5, (2000, 1, 3)) + rng.normal(0, 0.3, (2000, 3, 3))).astype(np.float32)
    vertices, faces = tri.reshape(-1, 3), np.arange(6000).reshape(-1, 3)
    dirs = rng.normal(0, 1, (20000, 3))
    dirs[:, 2] = -np.abs(dirs[:, 2]) - 3
    dirs = (dirs / np.linalg.norm(dirs, axis=1, keepdims=True)).astype(np.float32)
    origins = np.tile(np.array([[0, 0, 30]], np.float32), (len(dirs), 1))

    def hits(*config: bytes) -> tuple[np.ndarray, np.ndarray]:
        res = embree_scene(vertices, faces, *config).run(origins, dirs, output=1)
        return res["primID"].copy(), res["tfar"].copy()

    assert EMBREE_CONFIG == b"max_isa=avx2"
    prim, t = hits()
    assert (prim >= 0).sum() > 1000
    capped = hits(b"max_isa=avx2")
    np.testing.assert_array_equal(prim, capped[0])
    np.testing.assert_array_equal(t, capped[1])
    # the comparison can fail: SSE4.2's kernels put some of the same hits elsewhere by an ulp or so
    sse_prim, sse_t = hits(b"max_isa=sse4.2")
    hit = prim >= 0
    assert (sse_t[hit] != t[hit]).any()
    np.testing.assert_allclose(sse_t[hit], t[hit], rtol=1e-5)
