"""The colour pass leaves out the triangles no sample of it sees (simgen.occlusion), found from the
instance pass (simgen.instance_pass): shared edges and the certificate by hand, the instance pass
against pyrender's segmentation pass, and whole frames drawn with and without the culling, byte
for byte."""

from __future__ import annotations

import numpy as np
import pyrender
import pytest
from OpenGL import GL
from OpenGL.GL import shaders
from pyrender.constants import RenderFlags

from simgen import instance_pass, occlusion
from simgen import render as R
from simgen.sample import sample_world
from simgen.spec import load_spec

W, H = 64, 48


def test_adjacency_pairs_the_triangles_on_each_shared_edge():
    """Two triangles of a quad share its diagonal; a third on one of its edges makes that edge
    shared by three, which counts as no pair (llvmpipe covers a point of it by any of them)."""
    keys = np.array([[0, 1, 2], [0, 2, 3], [2, 1, 4], [1, 2, 5]])
    adj = occlusion.adjacency(keys)
    assert adj[0].tolist() == [-1, -1, 1] and adj[1].tolist() == [0, -1, -1]
    assert adj[2].tolist() == [-1, -1, -1] and adj[3].tolist() == [-1, -1, -1]  # edge 1-2: three


def _hidden(tris: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """`occlusion.hidden` of screen triangles (n, 3, 3): x, y in pixels, window depth."""
    keys = np.arange(3 * len(tris)).reshape(-1, 3)
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    if len(tris) >= 2:
        keys[:2] = quad  # the first two triangles: a quad of shared corners
    front = np.ones((len(tris), 3), bool)
    return occlusion.hidden(occlusion.prepare(tris[..., 0], tris[..., 1], tris[..., 2], front, keys, W, H), seen)


def _wall(depth: float) -> np.ndarray:
    """A quad over the whole image at one depth, split along its diagonal."""
    c = np.array([[-10, -10], [W + 10, -10], [W + 10, H + 10], [-10, H + 10]], float)
    return np.array([np.c_[c[[0, 1, 2]], np.full(3, depth)], np.c_[c[[0, 2, 3]], np.full(3, depth)]])


def _seen_wall() -> np.ndarray:
    """The wall's two triangles as a pixel-centre pass sees them."""
    v, u = np.mgrid[0:H, 0:W] + 0.5
    return np.where(v > u * (H + 20) / (W + 20) + 10 - 10 * (H + 20) / (W + 20), 1, 0).astype(np.int64)


def test_a_triangle_behind_the_wall_is_hidden_one_before_it_or_on_it_is_not():
    """Behind the wall: hidden, whether or not it straddles the diagonal (the samples along it are
    covered by one of the two triangles that share it). A triangle just in front of the wall, or
    in its plane, may win samples: kept. So is one whose corner lies nearer than the wall."""
    small = np.array([[20.3, 10.2], [40.7, 12.1], [30.1, 30.6]])
    behind = np.c_[small, np.full(3, 0.9)]
    level = np.c_[small, np.full(3, 0.5)]
    front = np.c_[small, np.full(3, 0.4999)]
    reaching = np.c_[small, [0.9, 0.9, 0.4]]
    tris = np.concatenate([_wall(0.5), [behind, level, front, reaching]])
    got = _hidden(tris, _seen_wall())
    assert got.tolist() == [False, False, True, False, False, False]


def test_a_pixel_with_nothing_seen_at_its_centre_hides_nothing():
    """Where the instance pass saw nothing of the layers (the sky, a lamp), no bound: a triangle
    reaching such a pixel is kept, however deep."""
    seen = _seen_wall()
    seen[20:23, 30:33] = -1
    behind = np.c_[np.array([[20.3, 10.2], [40.7, 12.1], [30.1, 30.6]]), np.full(3, 0.9)]
    away = np.c_[np.array([[2.3, 40.2], [8.7, 41.1], [5.1, 46.6]]), np.full(3, 0.9)]
    got = _hidden(np.concatenate([_wall(0.5), [behind, away]]), seen)
    assert got.tolist() == [False, False, False, True]


def test_a_triangle_off_the_image_is_hidden_one_across_the_near_plane_is_kept():
    tris = np.concatenate([_wall(0.5), [np.c_[np.array([[80.0, 10.0], [90.0, 10.0], [85.0, 20.0]]),
                                              np.full(3, 0.3)]]])
    got = _hidden(tris, _seen_wall())
    assert got.tolist() == [False, False, True]
    x, y, z = (tris[..., k] for k in range(3))
    front = np.ones((len(tris), 3), bool)
    front[2, 0] = False  # a corner behind the camera: its screen position means nothing
    keys = np.arange(3 * len(tris)).reshape(-1, 3)
    assert not occlusion.hidden(occlusion.prepare(x, y, z, front, keys, W, H), _seen_wall())[2]


def test_depths_as_pyrenders_blit_and_read_by_hand():
    """A 24-bit depth through float32 and back (times 1 / (2^24 - 1), then 2^24 - 1, rounded):
    some move up one step (8388607, 16777214: float32 rounds the product above them), others and
    the largest depth stay; read, each is divided by 2^24 - 1 and made camera z as pyrender does
    (0 where nothing is drawn); against numpy's float32 operators on a million more depths."""
    near, far = 0.3, 400.0
    z24 = np.r_[[0, 2, 8388607, 8388608, 16777214, 16777215],
                np.random.default_rng(0).integers(0, 1 << 24, 1_000_000)].astype(np.uint32)[None]
    moved = np.array([0, 2, 8388608, 8388608, 16777215, 16777215])
    f32 = np.float32
    back = np.round(z24.astype(f32) * f32(1.0 / 16777215) * f32(16777215))
    assert np.array_equal(back[0, :6], moved)
    z = (np.minimum(back, 16777215) / 16777215.0).astype(f32)
    want = (2.0 * near * far) / (far + near - (2.0 * z - 1.0) * (far - near))
    want[z == 1.0] = 0.0
    actor, triangle = np.array([0, 7]), np.array([-1, 3])
    inst, depth, seen = instance_pass.resolve(np.ones_like(z24), z24, actor, triangle, near, far)
    assert np.array_equal(depth.view(np.uint32), want.view(np.uint32)) and depth[0, 5] == 0.0
    assert (inst == 7).all() and (seen == 3).all()


_PLAIN: dict[tuple[int, int], pyrender.OffscreenRenderer] = {}


def _plain(width: int, height: int) -> pyrender.OffscreenRenderer:
    """pyrender's own renderer, with its own reads (render.renderer's reads colour only); kept
    for the process: deleting one ends the EGL display the others share."""
    if (width, height) not in _PLAIN:
        _PLAIN[width, height] = pyrender.OffscreenRenderer(width, height)
    return _PLAIN[width, height]


@pytest.mark.parametrize("spec, frame", [("scenes/urban.yaml", 0), ("scenes/variations.yaml", 14),
                                         ("scenes/variations.yaml", 0)])
def test_the_instance_pass_draws_as_pyrenders_segmentation_pass(spec, frame):
    """Actor ids and depth as pyrender's segmentation pass gives them for the same nodes: the
    triangles, poses and draw order (transparent nodes last) the instance pass was given."""
    world = sample_world(load_spec(spec), 0, frame)
    built = R.build_scene(world)
    r = R.renderer(world.rig.width, world.rig.height)
    seen = built.instance_pass(r)
    scene = R._Scene()
    seg = {}
    for i in built.instances:
        alpha = np.full((len(i.draw.tris) * 3, 4), 0.5 if i.draw.transparent else 1.0)
        mesh = pyrender.Mesh([pyrender.Primitive(positions=i.draw.tris.reshape(-1, 3).astype(np.float32), color_0=alpha)])
        seg[scene.add(mesh, pose=i.draw.pose)] = (i.actor % 256, i.actor // 256, 0)
    scene.add_node(pyrender.Node(camera=built.scene.main_camera_node.camera,
                                 matrix=built.scene.get_pose(built.scene.main_camera_node)))
    ids, depth = _plain(world.rig.width, world.rig.height).render(scene, flags=RenderFlags.SEG, seg_node_map=seg)
    assert np.array_equal(ids[..., 0] + 256 * ids[..., 1].astype(np.uint16), seen.instance)
    assert np.array_equal(depth, seen.depth)
    assert seen.instance.any()


@pytest.mark.parametrize("spec, frame, mode", [("scenes/urban.yaml", 0, "lit"),
                                               ("scenes/urban.yaml", 3, "lit"),
                                               ("scenes/variations.yaml", 14, "pbr"),
                                               ("scenes/variations.yaml", 0, "thermal")])
def test_culling_leaves_every_pixel_as_it_was(spec, frame, mode, monkeypatch):
    """The same world rendered with the hidden triangles left out and with every one drawn:
    colour, depth and instance maps byte for byte, while most triangles of urban.yaml's colour
    pass were left out."""
    spec = load_spec(spec)
    world = sample_world(spec, spec.seed, frame)
    assert R._Shader(world, np.zeros(3)).mode == mode
    built = R.build_scene(world)
    r = R.renderer(world.rig.width, world.rig.height)
    seen = built.instance_pass(r)
    hidden = built._hidden(r, seen.triangle)
    culled = R.render(world)
    monkeypatch.setattr(occlusion, "hidden", lambda t, seen: np.zeros(len(t.x), bool))
    whole = R.render(world)
    for a, b in ((culled.color, whole.color), (culled.depth, whole.depth), (culled.instance, whole.instance)):
        assert np.array_equal(a, b)
    assert hidden.mean() > (0.5 if mode == "lit" else 0.0)


_FETCH = ("""#version 330 core
void main() { gl_Position = vec4((gl_VertexID & 1) * 4.0 - 1.0, (gl_VertexID >> 1) * 4.0 - 1.0, 0.0, 1.0); }""",
          """#version 330 core
uniform sampler2DMS image;
uniform int s;
out vec4 colour;
void main() { colour = texelFetch(image, ivec2(gl_FragCoord.xy), s); }""")


def _samples(r: pyrender.OffscreenRenderer) -> list[np.ndarray]:
    """Each of the four samples of the renderer's last multisampled colour buffer, (H, W, 4)."""
    rr, W, H = r._renderer, r.viewport_width, r.viewport_height
    r._platform.make_current()
    tex = GL.glGenTextures(1)
    GL.glBindTexture(GL.GL_TEXTURE_2D_MULTISAMPLE, tex)
    GL.glTexImage2DMultisample(GL.GL_TEXTURE_2D_MULTISAMPLE, 4, GL.GL_RGBA8, W, H, GL.GL_TRUE)
    fb = GL.glGenFramebuffers(1)
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fb)
    GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D_MULTISAMPLE, tex, 0)
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, rr._main_fb_ms)
    GL.glBlitFramebuffer(0, 0, W, H, 0, 0, W, H, GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST)
    program = shaders.compileProgram(shaders.compileShader(_FETCH[0], GL.GL_VERTEX_SHADER),
                                     shaders.compileShader(_FETCH[1], GL.GL_FRAGMENT_SHADER))
    GL.glBindVertexArray(GL.glGenVertexArrays(1))
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, rr._main_fb)
    GL.glDisable(GL.GL_DEPTH_TEST)
    GL.glDisable(GL.GL_BLEND)
    GL.glUseProgram(program)
    GL.glBindTexture(GL.GL_TEXTURE_2D_MULTISAMPLE, tex)
    out = []
    for s in range(4):
        GL.glUniform1i(GL.glGetUniformLocation(program, "s"), s)
        GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
        out.append(np.frombuffer(GL.glReadPixels(0, 0, W, H, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE), np.uint8)
                   .reshape(H, W, 4).astype(np.int64))
    GL.glUseProgram(0)
    r._platform.make_uncurrent()
    return out


@pytest.mark.parametrize("spec, frame", [("scenes/urban.yaml", 1), ("scenes/urban.yaml", 8)])
def test_no_triangle_that_wins_a_sample_is_left_out(spec, frame):
    """The colour pass's layers drawn as pyrender draws them, each triangle in a colour of its own
    number, and every sample of the multisampled image read: no triangle the culling leaves out
    is any sample's, and most it keeps are (a triangle that wins no sample changes no byte; one
    that wins one may)."""
    world = sample_world(load_spec(spec), 0, frame)
    built = R.build_scene(world)
    r = R.renderer(world.rig.width, world.rig.height)
    hidden = built._hidden(r, built.instance_pass(r).triangle)
    scene, first = R._Scene(), 1
    for layer in built.layers:
        primitives = []
        for corners in layer.corners:
            ids = np.repeat(np.arange(first, first + len(corners)), 3)
            first += len(corners)
            colour = np.stack([ids % 256, ids // 256 % 256, ids // 65536, np.full(len(ids), 128)], 1) / 255.0
            primitives.append(pyrender.Primitive(positions=corners.reshape(-1, 3), color_0=colour, material=R._PLAIN))
        scene.add_node(pyrender.Node(mesh=R._Mesh(primitives, layer.node.mesh.is_transparent), matrix=layer.node.matrix))
    scene.add_node(pyrender.Node(camera=built.scene.main_camera_node.camera,
                                 matrix=built.scene.get_pose(built.scene.main_camera_node)))
    plain = _plain(world.rig.width, world.rig.height)
    plain.render(scene, flags=RenderFlags.FLAT | RenderFlags.RGBA)
    wins = np.zeros(first, bool)
    for sample in _samples(plain):
        wins[np.unique(sample[..., 0] + 256 * sample[..., 1] + 65536 * sample[..., 2])] = True
    wins = wins[1:]  # number 0: the background
    assert wins.sum() > 1000 and not (hidden & wins).any()
    assert hidden.mean() > 0.7
