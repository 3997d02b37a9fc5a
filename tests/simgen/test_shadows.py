"""Sun shadows (simgen.shadows) against the exact shadow of a box on the ground."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from simgen.materials import ASPHALT, FOLIAGE
from simgen.meshes import box
from simgen.shadows import SOFTEN, STEP, Occluders, sun_shadow
from simgen.world import Material, Part

F, N = 100.0, 101  # a 101 x 101 camera 20 m above the ground, looking straight down
K = np.array([[F, 0.0, 50.0], [0.0, F, 50.0], [0.0, 0.0, 1.0]])
CAM2_FROM_WORLD = np.array([[1.0, 0, 0, 0], [0, -1.0, 0, 0], [0, 0, -1.0, 20.0], [0, 0, 0, 1.0]])


def _casters(material: Material) -> Occluders:
    """A ground square and a floating box (world frame)."""
    ground = trimesh.Trimesh([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]],
                             [[0, 1, 2], [0, 2, 3]], process=False)
    parts = [Part(ground, ASPHALT), Part(box(-2, 2, -2, 2, 5, 6), material)]
    return Occluders.of_parts(parts, np.concatenate([p.mesh.vertices[p.mesh.faces] for p in parts]))


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
