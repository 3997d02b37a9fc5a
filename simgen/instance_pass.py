"""The instance pass: the triangle the camera sees at each pixel centre, and its depth.

pyrender's segmentation pass drew each node in one colour. This pass draws the same nodes in the
same order through pyrender's own segmentation vertex shader, so the depth and the winner at
every pixel come out as they did, but its fragment shader writes the running number of the
triangle instead: that names the actor (simgen.render's instance map) and the triangle that the
colour pass's culling starts from (simgen.occlusion). All draws share one vertex buffer.

pyrender drew into 4x multisampled buffers with multisampling off and resolved them by blits,
whose depth blit moves a depth by a float32 round trip. This pass draws into single-sample
buffers, a quarter of the writes and no blits, and makes the same round trip on the depth it
reads (`resolve`).
"""

from __future__ import annotations

import ctypes
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
import pyrender
from OpenGL import GL
from pyrender.shader_program import ShaderProgram

_VERTEX = Path(pyrender.__file__).parent / "shaders" / "segmentation.vert"
_FRAGMENT = """#version 330 core
uniform uint first;
out uint id;

void main()
{
    id = first + uint(gl_PrimitiveID);
}
"""
# pyrender's location of the instance matrix for a primitive with positions only; the matrix is the
# identity, given here as constant attributes rather than a buffer.
_INST_M_LOC = 1
_Z24 = 0xFFFFFF  # the largest 24-bit depth


@dataclass
class Draw:
    """One node of the instance pass: its triangles (n, 3, 3) in its frame, its pose as pyrender
    keeps a node's matrix, whether pyrender counts it transparent (drawn after the solid ones)."""

    tris: np.ndarray
    pose: np.ndarray
    transparent: bool


def order(draws: list[Draw], camera: np.ndarray) -> list[int]:
    """pyrender's draw order: the solid nodes farthest from the camera position first, then the
    transparent ones, each in the order given among equally far ones."""
    far = [-np.linalg.norm(d.pose[:3, 3] - camera) for d in draws]
    solid = sorted((i for i, d in enumerate(draws) if not d.transparent), key=lambda i: far[i])
    return solid + sorted((i for i, d in enumerate(draws) if d.transparent), key=lambda i: far[i])


class _Program(ShaderProgram):
    """pyrender's shader program with pyrender's segmentation vertex shader (read and set up as
    pyrender does) and the fragment shader above."""

    def __init__(self):
        super().__init__(str(_VERTEX), "", None, defines={"INST_M_LOC": _INST_M_LOC})

    def _load(self, shader_filename):
        return super()._load(shader_filename) if shader_filename else _FRAGMENT


@dataclass
class _Target:
    """The GL objects of one context and image size."""

    program: _Program
    framebuffer: int
    vao: int
    vbo: int


_TARGETS: dict[tuple[int, int, int], _Target] = {}


def _renderbuffer(fmt: int, width: int, height: int) -> int:
    rb = GL.glGenRenderbuffers(1)
    GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, rb)
    GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, fmt, width, height)
    return rb


def _framebuffer(width: int, height: int) -> int:
    fb = GL.glGenFramebuffers(1)
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fb)
    GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER,
                                 _renderbuffer(GL.GL_R32UI, width, height))
    GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER,
                                 _renderbuffer(GL.GL_DEPTH_COMPONENT24, width, height))
    return fb


def _target(width: int, height: int) -> _Target:
    """The current context's objects for this size, made once (keyed by process: a forked child
    has a context of its own)."""
    key = (os.getpid(), width, height)
    if key not in _TARGETS:
        program = _Program()
        program._add_to_context()
        _TARGETS[key] = _Target(program, _framebuffer(width, height), GL.glGenVertexArrays(1), GL.glGenBuffers(1))
    return _TARGETS[key]


def _upload(target: _Target, positions: np.ndarray) -> None:
    GL.glBindVertexArray(target.vao)
    GL.glBindBuffer(GL.GL_ARRAY_BUFFER, target.vbo)
    GL.glBufferData(GL.GL_ARRAY_BUFFER, positions.nbytes, positions, GL.GL_STREAM_DRAW)
    GL.glVertexAttribPointer(0, 3, GL.GL_FLOAT, GL.GL_FALSE, 12, ctypes.c_void_p(0))
    GL.glEnableVertexAttribArray(0)
    for i in range(4):  # the identity
        GL.glDisableVertexAttribArray(_INST_M_LOC + i)
        GL.glVertexAttrib4f(_INST_M_LOC + i, *(float(j == i) for j in range(4)))


def _state(width: int, height: int) -> None:
    """pyrender's state for its segmentation pass."""
    GL.glViewport(0, 0, width, height)
    GL.glEnable(GL.GL_DEPTH_TEST)
    GL.glDepthMask(GL.GL_TRUE)
    GL.glDepthFunc(GL.GL_LESS)
    GL.glDepthRange(0.0, 1.0)
    GL.glEnable(GL.GL_CULL_FACE)
    GL.glCullFace(GL.GL_BACK)
    GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
    GL.glClearBufferuiv(GL.GL_COLOR, 0, np.zeros(4, np.uint32))
    GL.glClearDepth(1.0)
    GL.glClear(GL.GL_DEPTH_BUFFER_BIT)


def resolve(ids: np.ndarray, z24: np.ndarray, actor: np.ndarray, triangle: np.ndarray, near: float,
            far: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel of `draw`'s image (triangle numbers `ids`, 24-bit depths `z24`): the actor id and
    the triangle named by `actor` and `triangle` (indexed by the numbers: 0 for none), and the
    depth in metres as pyrender's segmentation pass gave it (0 where nothing is drawn): its depth
    blit took a depth to float32 (times 1 / (2^24 - 1)) and back (times 2^24 - 1, rounded to
    even), which moves some up by one step, its read divided by 2^24 - 1, and it made window
    depths camera z with the camera's near and far planes, all in float32."""
    H, W = ids.shape
    out = (np.empty((H, W), np.uint16), np.empty((H, W), np.float32), np.empty((H, W), np.int64))
    _resolve(ids, z24, actor.astype(np.uint16), triangle.astype(np.int64), near, far, *out)
    return out


@numba.njit(cache=True, nogil=True)
def _resolve(ids, z24, actor, triangle, near, far, instance, depth, seen):
    f1, f2 = np.float32(1.0 / _Z24), np.float32(_Z24)
    c1, c2, c3 = np.float32(far - near), np.float32(far + near), np.float32(2.0 * near * far)
    for r in range(ids.shape[0]):
        for c in range(ids.shape[1]):
            instance[r, c], seen[r, c] = actor[ids[r, c]], triangle[ids[r, c]]
            z = np.float32(np.float64(min(np.round(np.float32(z24[r, c]) * f1 * f2), f2)) / _Z24)
            depth[r, c] = 0.0 if z == np.float32(1.0) else c3 / (c2 - (np.float32(2.0) * z - np.float32(1.0)) * c1)


def _read(target: _Target, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, target.framebuffer)
    ids = GL.glReadPixels(0, 0, width, height, GL.GL_RED_INTEGER, GL.GL_UNSIGNED_INT)
    depth = GL.glReadPixels(0, 0, width, height, GL.GL_DEPTH_COMPONENT, GL.GL_UNSIGNED_INT)  # 24 bits, high
    return (np.frombuffer(ids, np.uint32).reshape(height, width)[::-1],
            np.frombuffer(depth, np.uint32).reshape(height, width)[::-1] >> 8)


def draw(draws: list[Draw], view: np.ndarray, projection: np.ndarray, width: int, height: int,
         meanwhile: Callable[[], None] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) uint32 triangle at each pixel (0 none, else 1 + its place in `draws`' triangles,
    taken in the order given) and (H, W) 24-bit depth (2^24 - 1 where none), image rows top
    down (`resolve` reads them). `draws` in drawing order; view and projection matrices as pyrender's. `meanwhile`, if
    given, runs while llvmpipe rasterizes. The caller makes the renderer's context current."""
    target = _target(width, height)
    first = np.cumsum([0, *(len(d.tris) for d in draws)])
    positions = np.empty((3 * first[-1], 3), np.float32)  # as pyrender uploads each: float32
    for d, start in zip(draws, first):
        positions[3 * start:3 * (start + len(d.tris))] = d.tris.reshape(-1, 3)
    _upload(target, positions)
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, target.framebuffer)
    _state(width, height)
    program = target.program
    program._bind()
    program.set_uniform("V", view)
    program.set_uniform("P", projection)
    for d, start in zip(draws, first):
        program.set_uniform("M", d.pose)
        program.set_uniform("first", int(start) + 1, unsigned=True)
        GL.glDrawArrays(GL.GL_TRIANGLES, 3 * int(start), 3 * len(d.tris))
    program._unbind()
    GL.glBindVertexArray(0)
    if meanwhile is not None:
        GL.glFlush()
        meanwhile()
    return _read(target, width, height)
