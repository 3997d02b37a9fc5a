"""The colour pass's hidden triangles: those that no sample of it can see, found from the instance
pass, so that the colour pass leaves them out and draws the same bytes.

llvmpipe spends the colour pass (4x multisampled, simgen.render) per triangle and per 4x4 block
it touches, hidden or not, and most triangles in view lie behind others (on urban.yaml about nine
in ten: trees behind houses, yards behind walls, the far side of every crown). A triangle that
wins no sample changes no byte, and leaving out triangles that win none changes no winner: at
every sample the nearest triangle (the first drawn among equally near ones) stays.

The instance pass names the triangle seen at each pixel centre. From the geometry of those
triangles, as the colour pass draws them, each of a pixel's four samples gets a bound of how deep
the surface covering it lies at most (`_certify`): a sample counts as covered by a triangle only
where it lies inside all three of its edges by COVER_PX, or, within COVER_PX of an edge that two
triangles share (the same vertices: llvmpipe covers such a sample by exactly one of them), inside
the other edges of both (`_across`). The triangle containing a sample need not be the one seen at
a centre: it is found among those seen at the pixel and its eight neighbours, or by walking
across shared edges from them. A triangle is hidden (`hidden`) where every sample it may cover
has a bound nearer than the nearest depth it may draw there (its plane at the pixel centre, or its
nearest corner), by margins that hold llvmpipe's float32 transform and set-up, its fixed-point
coverage and its 24-bit depth; triangles it may clip (near plane, guard band) and slivers are
kept. What needs no image (`prepare`) is made while llvmpipe draws the instance pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

# The colour pass's four samples in a pixel (glGetMultisamplefv on llvmpipe's 4x buffers), in image
# coordinates: x to the right and y down from the pixel's top left corner (GL counts y up).
SAMPLES = np.array([[0.375, 0.875], [0.875, 0.625], [0.125, 0.375], [0.625, 0.125]])
# A sample this far (px) inside a triangle's edge is on that side whatever llvmpipe's 1/256 px
# vertex snapping and float32 transform do to the edge.
COVER_PX = 0.01
# A pixel centre this far inside all edges of a triangle has its four samples (within 0.4 px of it)
# COVER_PX inside them.
INNER_PX = COVER_PX + 0.4
# A triangle may cover a sample of a pixel only where the pixel's centre lies within this distance
# (px) of its box and of its three edge lines: the samples lie within 0.4 px of the centre.
REACH_PX = 0.75
# Window depth: llvmpipe's float32 vertex transform and depth interpolation and its 24-bit depth
# (6e-8 a step) stay well within it; a triangle's depth gradient adds its slope over SLOPE_PX, over
# half a pixel (a depth taken at the pixel centre) and a hundredth of its depth range
# (interpolation of a long, narrow triangle).
DEPTH_EPS = 4e-6
SLOPE_PX = 0.01
SPAN_SHARE = 0.01
# Triangles whose corners lie farther than this (px) from the image, or whose height is below this
# share of their longest edge, take no part: llvmpipe may clip the former, and both have edges and
# depth planes that its float32 set-up computes less well.
GUARD_PX = 4096.0
MIN_ASPECT = 1e-4
WALK = 6  # steps across shared edges from a triangle seen at a pixel centre towards a sample
TILE = 8  # px: a triangle whose box lies over tiles all bounded nearer than it is hidden at once
# A pixel and its eight neighbours, row and column offsets.
_DR = np.array([0, -1, 1, 0, 0, -1, -1, 1, 1])
_DC = np.array([0, 0, 0, -1, 1, -1, 1, -1, 1])


def screen(points: np.ndarray, clip_from_frame: np.ndarray, width: int, height: int
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Window x, y (image rows, down) and depth of (..., 3) float32 points in one frame, and
    whether each lies in front of the camera, each shaped as the points less their last axis."""
    v = points.reshape(-1, 3).astype(np.float64)
    clip = v @ clip_from_frame[:3, :3].T + clip_from_frame[:3, 3]
    w = v @ clip_from_frame[3, :3] + clip_from_frame[3, 3]
    front = w > 0
    inv = 1.0 / np.where(front, w, 1.0)
    x = (clip[:, 0] * inv + 1.0) * (width / 2)
    y = height - (clip[:, 1] * inv + 1.0) * (height / 2)
    z = (clip[:, 2] * inv + 1.0) / 2
    shape = points.shape[:-1]
    return x.reshape(shape), y.reshape(shape), z.reshape(shape), front.reshape(shape)


def adjacency(keys: np.ndarray) -> np.ndarray:
    """(n, 3) int64: the triangle across each edge (corner k to corner k + 1) of triangles whose
    corners are the shared vertices `keys` (n, 3), where exactly two triangles share that edge;
    -1 elsewhere."""
    out = np.full((len(keys), 3), -1, np.int64)
    if len(keys):
        _pair_edges(np.ascontiguousarray(keys, np.int64), out)
    return out


@numba.njit(cache=True, nogil=True)
def _pair_edges(keys, out):
    """`adjacency` from each vertex's triangles (a counting sort of the corners by vertex): the
    triangles on edge (a, b) are those of a's that have b too."""
    n, nv = keys.shape[0], keys.max() + 1
    start = np.zeros(nv + 1, np.int64)
    for t in range(n):
        for k in range(3):
            start[keys[t, k] + 1] += 1
    for v in range(nv):
        start[v + 1] += start[v]
    fill, around = start[:-1].copy(), np.empty(3 * n, np.int64)
    for t in range(n):
        for k in range(3):
            v = keys[t, k]
            around[fill[v]] = t
            fill[v] += 1
    for t in range(n):
        for k in range(3):
            a, b = keys[t, k], keys[t, (k + 1) % 3]
            other, found = -1, 0
            for i in range(start[a], start[a + 1]):
                u = around[i]
                if u != t and (keys[u, 0] == b or keys[u, 1] == b or keys[u, 2] == b):
                    other = u
                    found += 1
            if found == 1:
                out[t, k] = other


@numba.njit(cache=True, nogil=True)
def _setup(x, y, z, front, width, height, edges, plane, slack, low, centre, ok):
    """Per triangle: normalised edge functions (inside >= 0, in px), depth plane, its depth slack
    (how far from its plane at a pixel centre it may draw in that pixel), the lowest depth it may
    draw anywhere, its centroid, and whether it takes part."""
    for i in range(x.shape[0]):
        ok[i] = False
        good = True
        for k in range(3):
            if (not front[i, k] or not 1e-5 < z[i, k] < 1.0 - 1e-5
                    or abs(x[i, k] - width / 2) > GUARD_PX or abs(y[i, k] - height / 2) > GUARD_PX):
                good = False
        if not good:
            continue
        x0, y0, x1, y1, x2, y2 = x[i, 0], y[i, 0], x[i, 1], y[i, 1], x[i, 2], y[i, 2]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        longest = 0.0
        for k in range(3):
            dx, dy = x[i, (k + 1) % 3] - x[i, k], y[i, (k + 1) % 3] - y[i, k]
            longest = max(longest, math.sqrt(dx * dx + dy * dy))
        if abs(area) < max(1e-6, MIN_ASPECT * longest * longest):
            continue
        sign = 1.0 if area > 0 else -1.0
        for k in range(3):
            ax, ay, bx, by = x[i, k], y[i, k], x[i, (k + 1) % 3], y[i, (k + 1) % 3]
            a, b = (ay - by) * sign, (bx - ax) * sign
            n = math.sqrt(a * a + b * b)
            edges[i, k, 0], edges[i, k, 1], edges[i, k, 2] = a / n, b / n, -(a * ax + b * ay) / n
        z0, z1, z2 = z[i, 0], z[i, 1], z[i, 2]
        p = ((z1 - z0) * (y2 - y0) - (z2 - z0) * (y1 - y0)) / area
        q = ((x1 - x0) * (z2 - z0) - (x2 - x0) * (z1 - z0)) / area
        plane[i, 0], plane[i, 1], plane[i, 2] = p, q, z0 - p * x0 - q * y0
        zmin, zmax = min(z0, min(z1, z2)), max(z0, max(z1, z2))
        base = DEPTH_EPS + SPAN_SHARE * (zmax - zmin)
        slope = abs(p) + abs(q)
        slack[i] = base + (SLOPE_PX + 0.5) * slope
        low[i] = zmin - base - (SLOPE_PX + REACH_PX) * slope
        centre[i, 0], centre[i, 1] = (x0 + x1 + x2) / 3, (y0 + y1 + y2) / 3
        ok[i] = True


@numba.njit(cache=True, nogil=True, inline="always")
def _walk(edges, plane, slack, adj, ok, t, x, y, steps):
    """Depth bound of what covers (x, y), from triangle t across shared edges towards the point
    (at most `steps` of them); inf where no cover is certain; -2 - (3 u + k) where the point lies
    within COVER_PX of edge k of triangle u and inside its other two edges (`_across` decides).
    The hot loop stays free of the rare case's array reads: llvm compiles it several times faster."""
    for _ in range(steps + 1):
        e0 = edges[t, 0, 0] * x + edges[t, 0, 1] * y + edges[t, 0, 2]
        e1 = edges[t, 1, 0] * x + edges[t, 1, 1] * y + edges[t, 1, 2]
        e2 = edges[t, 2, 0] * x + edges[t, 2, 1] * y + edges[t, 2, 2]
        k, least = 0, e0
        if e1 < least:
            k, least = 1, e1
        if e2 < least:
            k, least = 2, e2
        if least >= COVER_PX:
            return plane[t, 0] * x + plane[t, 1] * y + plane[t, 2] + slack[t]
        if least > -COVER_PX:
            if (k == 0 or e0 >= COVER_PX) and (k == 1 or e1 >= COVER_PX) and (k == 2 or e2 >= COVER_PX):
                return -2.0 - (3 * t + k)
            return np.inf
        if steps == 0:
            return np.inf
        t = adj[t, k]
        if t < 0 or not ok[t]:
            return np.inf
    return np.inf


@numba.njit(cache=True, nogil=True)
def _certify(seen, edges, plane, slack, adj, ok, samples, out):
    """out[r, c, s]: a bound of the depth of what covers sample s of the pixel, inf where no cover
    is certain (or no triangle of the layers is seen at the pixel centre), or where the sample
    lies on a shared edge `_walk`'s mark for `_across`. Each sample's cover is searched among
    the triangles seen at the pixel and its neighbours (each once), then by walking from them
    across shared edges towards the sample."""
    H, W = seen.shape
    starts = np.empty(9, np.int64)
    for r in range(H):
        for c in range(W):
            out[r, c, :] = np.inf
            own = seen[r, c]
            if own < 0 or not ok[own]:
                continue
            xc, yc = c + 0.5, r + 0.5
            if (edges[own, 0, 0] * xc + edges[own, 0, 1] * yc + edges[own, 0, 2] >= INNER_PX
                    and edges[own, 1, 0] * xc + edges[own, 1, 1] * yc + edges[own, 1, 2] >= INNER_PX
                    and edges[own, 2, 0] * xc + edges[own, 2, 1] * yc + edges[own, 2, 2] >= INNER_PX):
                for s in range(samples.shape[0]):  # all four well inside the triangle seen
                    out[r, c, s] = (plane[own, 0] * (c + samples[s, 0]) + plane[own, 1] * (r + samples[s, 1])
                                    + plane[own, 2] + slack[own])
                continue
            n = 0
            for s in range(samples.shape[0]):
                x, y = c + samples[s, 0], r + samples[s, 1]
                best = _walk(edges, plane, slack, adj, ok, own, x, y, 0)
                mark = best if best < -1.0 else 0.0  # on a shared edge: the first such answer
                if best == np.inf or mark < 0.0:
                    best = np.inf
                    if n == 0:  # the pixel's neighbours, gathered once
                        for j in range(9):
                            rr, cc = r + _DR[j], c + _DC[j]
                            if 0 <= rr < H and 0 <= cc < W and seen[rr, cc] >= 0 and ok[seen[rr, cc]]:
                                known = False
                                for q in range(n):
                                    known |= starts[q] == seen[rr, cc]
                                if not known:
                                    starts[n] = seen[rr, cc]
                                    n += 1
                    for steps in (0, WALK):
                        for j in range(n):
                            if best < np.inf or (j == 0 and steps == 0):  # own, directly: done above
                                continue
                            best = _walk(edges, plane, slack, adj, ok, starts[j], x, y, steps)
                            if best < -1.0:
                                mark = best if mark == 0.0 else mark
                                best = np.inf
                out[r, c, s] = mark if best == np.inf and mark < 0.0 else best


@numba.njit(cache=True, nogil=True)
def _across(edges, plane, slack, centre, adj, ok, samples, out):
    """The samples `_certify` left on shared edges (marked -2 - (3 t + k)): a sample within
    COVER_PX of edge k of triangle t and inside its other two edges is covered by t or by the
    triangle across that edge, where that one lies on the edge's other side and has the sample
    inside its own other two edges (llvmpipe covers a point of an edge two triangles share by
    exactly one of them); the deeper of the two bounds is the sample's, or inf."""
    H, W, S = out.shape
    for r in range(H):
        for c in range(W):
            for s in range(S):
                if not out[r, c, s] < -1.0:
                    continue
                tk = int(-2.0 - out[r, c, s])
                t, k = tk // 3, tk % 3
                x, y = c + samples[s, 0], r + samples[s, 1]
                u = adj[t, k]
                depth = np.inf
                if (u >= 0 and ok[u] and edges[t, k, 0] * centre[u, 0] + edges[t, k, 1] * centre[u, 1]
                        + edges[t, k, 2] < -COVER_PX):
                    f0 = edges[u, 0, 0] * x + edges[u, 0, 1] * y + edges[u, 0, 2]
                    f1 = edges[u, 1, 0] * x + edges[u, 1, 1] * y + edges[u, 1, 2]
                    f2 = edges[u, 2, 0] * x + edges[u, 2, 1] * y + edges[u, 2, 2]
                    j, near = 0, abs(f0)  # u's edge along the shared one
                    if abs(f1) < near:
                        j, near = 1, abs(f1)
                    if abs(f2) < near:
                        j = 2
                    if (adj[u, j] == t and (j == 0 or f0 >= COVER_PX) and (j == 1 or f1 >= COVER_PX)
                            and (j == 2 or f2 >= COVER_PX)):
                        depth = max(plane[t, 0] * x + plane[t, 1] * y + plane[t, 2] + slack[t],
                                    plane[u, 0] * x + plane[u, 1] * y + plane[u, 2] + slack[u])
                out[r, c, s] = depth


@numba.njit(cache=True, nogil=True)
def _maxima(bound, pixels, tiles):
    """The largest bound of each pixel's samples (pixels) and of each TILE x TILE square from
    (0, 0) (tiles), in float32 rounded up: never below the bounds."""
    H, W = pixels.shape
    tiles[:] = -np.inf
    for r in range(H):
        for c in range(W):
            z = bound[r, c, 0]
            for s in range(1, bound.shape[2]):
                z = max(z, bound[r, c, s])
            v = np.float32(z)
            if v < z:
                v = np.nextafter(v, np.float32(np.inf))
            pixels[r, c] = v
            tiles[r // TILE, c // TILE] = max(tiles[r // TILE, c // TILE], v)


@numba.njit(cache=True, nogil=True)
def _within(tiles, x, y, i, low):
    """Whether every tile under triangle i's box, REACH_PX wider, has its bound below `low`."""
    th, tw = tiles.shape
    x0 = max(0, int(math.floor(min(x[i, 0], min(x[i, 1], x[i, 2])) - REACH_PX - 0.5)) // TILE)
    x1 = min(tw - 1, int(math.ceil(max(x[i, 0], max(x[i, 1], x[i, 2])) + REACH_PX)) // TILE)
    y0 = max(0, int(math.floor(min(y[i, 0], min(y[i, 1], y[i, 2])) - REACH_PX - 0.5)) // TILE)
    y1 = min(th - 1, int(math.ceil(max(y[i, 0], max(y[i, 1], y[i, 2])) + REACH_PX)) // TILE)
    for ty in range(y0, y1 + 1):
        for tx in range(x0, x1 + 1):
            if not tiles[ty, tx] < low:
                return False
    return True


@numba.njit(cache=True, nogil=True, inline="always")
def _span(edges, i, r, left, right, W):
    """The pixels of row r whose centres lie within REACH_PX of triangle i's edge lines and
    between `left` and `right`: first and last column (first > last where none)."""
    yc = r + 0.5
    lo, hi = left, right
    for k in range(3):
        a, rest = edges[i, k, 0], edges[i, k, 1] * yc + edges[i, k, 2] + REACH_PX
        if a > 0:
            lo = max(lo, -rest / a)
        elif a < 0:
            hi = min(hi, -rest / a)
        elif rest < 0:
            hi = -1.0
    if not lo <= hi:
        return 1, 0
    return max(0, int(math.ceil(lo - 0.5))), min(W - 1, int(math.floor(hi - 0.5)))


@numba.njit(cache=True, nogil=True)
def _samples_clear(bound, pixels, edges, plane, low, slack, samples, x, y, i):
    """Whether every sample triangle i may cover (within COVER_PX of all its edges) is bounded
    below the lowest depth the triangle may draw in that pixel: its plane at the pixel centre,
    less its slack, or its lowest anywhere."""
    H, W = bound.shape[:2]
    top = max(0, int(math.floor(min(y[i, 0], min(y[i, 1], y[i, 2])) - REACH_PX - 0.5)))
    bottom = min(H - 1, int(math.ceil(max(y[i, 0], max(y[i, 1], y[i, 2])) + REACH_PX)))
    left = max(0.0, min(x[i, 0], min(x[i, 1], x[i, 2])) - REACH_PX)
    right = min(float(W), max(x[i, 0], max(x[i, 1], x[i, 2])) + REACH_PX)
    for r in range(top, bottom + 1):
        a, b = _span(edges, i, r, left, right, W)
        for c in range(a, b + 1):
            nearest = max(low[i], plane[i, 0] * (c + 0.5) + plane[i, 1] * (r + 0.5) + plane[i, 2] - slack[i])
            if pixels[r, c] < nearest:
                continue
            for s in range(samples.shape[0]):
                xs, ys = c + samples[s, 0], r + samples[s, 1]
                if (edges[i, 0, 0] * xs + edges[i, 0, 1] * ys + edges[i, 0, 2] >= -COVER_PX
                        and edges[i, 1, 0] * xs + edges[i, 1, 1] * ys + edges[i, 1, 2] >= -COVER_PX
                        and edges[i, 2, 0] * xs + edges[i, 2, 1] * ys + edges[i, 2, 2] >= -COVER_PX
                        and not bound[r, c, s] < nearest):
                    return False
    return True


@numba.njit(cache=True, nogil=True)
def _hidden(bound, pixels, tiles, edges, plane, low, slack, ok, samples, x, y, out):
    """out[i]: no sample triangle i may cover is left where it could win: tried on the tiles
    under its box, then pixel by pixel and sample by sample."""
    for i in range(edges.shape[0]):
        out[i] = ok[i] and (_within(tiles, x, y, i, low[i])
                            or _samples_clear(bound, pixels, edges, plane, low, slack, samples, x, y, i))





@dataclass
class Triangles:
    """The colour pass's triangles as the culling reads them (`prepare`)."""

    x: np.ndarray  # (n, 3) window x of the corners
    y: np.ndarray  # (n, 3) image rows (down)
    edges: np.ndarray  # (n, 3, 3) normalised edge functions, inside >= 0
    plane: np.ndarray  # (n, 3) window depth = p x + q y + r
    slack: np.ndarray  # (n,) how far from its plane at a pixel centre it may draw in that pixel
    low: np.ndarray  # (n,) lowest depth it may draw anywhere
    centre: np.ndarray  # (n, 2)
    ok: np.ndarray  # (n,) bool: takes part
    adj: np.ndarray  # (n, 3) the triangle across each edge


def prepare(x: np.ndarray, y: np.ndarray, z: np.ndarray, front: np.ndarray, keys: np.ndarray,
            width: int, height: int) -> Triangles:
    """The colour pass's triangles: x, y, z, front their corners on screen (`screen`); keys (n, 3)
    their shared vertices (equal keys, equal bits). What needs no image, made while the instance
    pass draws."""
    n = len(x)
    t = Triangles(x, y, np.zeros((n, 3, 3)), np.zeros((n, 3)), np.zeros(n), np.zeros(n),
                  np.zeros((n, 2)), np.zeros(n, bool), adjacency(keys))
    _setup(x, y, z, front, width, height, t.edges, t.plane, t.slack, t.low, t.centre, t.ok)
    return t


def hidden(t: Triangles, seen: np.ndarray) -> np.ndarray:
    """(n,) bool: which of the colour pass's triangles win no sample. seen (H, W) int64: the
    triangle seen at each pixel centre, -1 where none of them."""
    H, W = seen.shape
    bound = np.empty((H, W, len(SAMPLES)))
    _certify(seen, t.edges, t.plane, t.slack, t.adj, t.ok, SAMPLES, bound)
    _across(t.edges, t.plane, t.slack, t.centre, t.adj, t.ok, SAMPLES, bound)
    pixels, tiles = np.empty((H, W), np.float32), np.empty((-(-H // TILE), -(-W // TILE)), np.float32)
    _maxima(bound, pixels, tiles)
    out = np.empty(len(t.x), bool)
    _hidden(bound, pixels, tiles, t.edges, t.plane, t.low, t.slack, t.ok, SAMPLES, t.x, t.y, out)
    return out
