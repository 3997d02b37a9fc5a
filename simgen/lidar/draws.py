"""A sweep's random numbers, each a function of (the sweep's key, the ray, the use).

A generator drawn in sequence makes every number depend on how many were drawn before it: one ray
whose pass through glass or leaves ends otherwise (a hit whose triangle two CPUs pick differently)
shifts every later draw, and the whole frame's noise is drawn afresh. Here each ray's numbers
come from Philox4x32-10 (Salmon, Moraes, Dror and Shaw, "Parallel random numbers: as easy as 1,
2, 3", SC 2011), a counter-based generator: the 128-bit counter (ray, use, block, 0) under the
sweep's 64-bit key gives four 32-bit words, and nothing else. One ray's outcome never moves
another ray's numbers. Integer arithmetic only, so every CPU gives the same words.

A ray's block (ray, 0, 0, 0) serves what every ray draws (`ray_words`): word DETECT its
drop-out and reading uniform, word CLAMP the clamp's scatter uniform, words NOISE and NOISE + 1
the first tries of its range noise, whose rare further tries take the blocks (ray, 1, b, 0).
The k-th surface a beam may go on through takes (ray, PASS + k, 0, 0). Uniforms are numpy's
float32 (a word's top 24 bits over 2 ** 24); normals run numpy's float32 ziggurat (its tables,
as numba ports them).
"""

from __future__ import annotations

import numba
import numpy as np
from numba.np.random._constants import fi_float, ki_float, wi_float, ziggurat_nor_inv_r_f, ziggurat_nor_r_f

_F32 = np.float32
_M0, _M1 = np.uint64(0xD2511F53), np.uint64(0xCD9E8D57)  # Philox4x32's multipliers
_W0, _W1 = np.uint32(0x9E3779B9), np.uint32(0xBB67AE85)  # its key schedule (Weyl sequence)
_32 = np.uint64(32)

# The words of a ray's block (module docstring), and the counter's second word of the rest.
DETECT, CLAMP, NOISE = 0, 1, 2
_MORE_NOISE, PASS = 1, 2


@numba.njit(cache=True, nogil=True, inline="always")
def philox(c0, c1, c2, c3, k0, k1):
    """Philox4x32-10 of the counter (c0, c1, c2, c3) under the key (k0, k1): four uint32 words.
    Kept in uint32 with the products in uint64, so numba vectorises a loop of them."""
    c0, c1, c2, c3, k0, k1 = (np.uint32(c0), np.uint32(c1), np.uint32(c2), np.uint32(c3), np.uint32(k0),
                              np.uint32(k1))
    for _ in range(10):
        p0 = _M0 * np.uint64(c0)
        p1 = _M1 * np.uint64(c2)
        c0, c1, c2, c3 = (np.uint32(p1 >> _32) ^ c1 ^ k0, np.uint32(p1), np.uint32(p0 >> _32) ^ c3 ^ k1,
                          np.uint32(p0))
        k0 = np.uint32(k0 + _W0)
        k1 = np.uint32(k1 + _W1)
    return c0, c1, c2, c3


@numba.njit(cache=True, nogil=True, inline="always")
def _uniform(word):
    """numpy's next_float: the word's top 24 bits over 2 ** 24."""
    return _F32(_F32(np.uint32(word) >> np.uint32(8)) * _F32(1.0) / _F32(16777216.0))


@numba.njit(cache=True, nogil=True)
def _blocks(k0, k1, rays, use, out):
    for i in range(rays.shape[0]):
        out[0, i], out[1, i], out[2, i], out[3, i] = philox(rays[i], use, 0, 0, k0, k1)


def _block_words(key: np.ndarray, rays: np.ndarray, use: int) -> np.ndarray:
    out = np.empty((4, len(rays)), np.uint32)
    _blocks(key[0], key[1], np.ascontiguousarray(rays, np.uint32), use, out)
    return out


def ray_words(key: np.ndarray, n: int) -> np.ndarray:
    """(4, n) uint32: row j holds word j of the blocks (ray, 0, 0, 0) of rays 0 .. n - 1."""
    return _block_words(key, np.arange(n, dtype=np.uint32), 0)


def to_uniform(words: np.ndarray) -> np.ndarray:
    """float32 in [0, 1) from uint32 words as numpy's next_float makes them: the top 24 bits over
    2 ** 24 (both steps exact in float32)."""
    return (words >> np.uint32(8)).astype(_F32) * _F32(1.0 / 16777216.0)


def uniforms(key: np.ndarray, rays: np.ndarray, use: int) -> np.ndarray:
    """(len(rays),) float32: the first word of each ray's block (ray, use, 0, 0) as a uniform."""
    return to_uniform(_block_words(key, rays, use)[0])


@numba.njit(cache=True, nogil=True)
def _word(k0, k1, ray, words, n):
    """The n-th word of a ray's range-noise stream: its block's words NOISE and NOISE + 1, then
    the blocks (ray, _MORE_NOISE, b, 0), four words each."""
    if n < 2:
        return words[NOISE + n, ray]
    w = philox(ray, _MORE_NOISE, (n - 2) >> 2, 0, k0, k1)
    m = (n - 2) & 3
    return w[0] if m == 0 else w[1] if m == 1 else w[2] if m == 2 else w[3]


@numba.njit(cache=True, nogil=True)
def _slow_normal(k0, k1, ray, words, r, wi, ki, fi, r_f, inv_r_f):
    """The ziggurat's rare branches for a first word r that missed its box: numpy's
    random_standard_normal_f, same operations and precisions (the tail beyond r_f for box 0, else
    the wedge test; a rejected draw starts over on the next word)."""
    one, two = _F32(1.0), _F32(2.0)
    n = 1
    while True:
        idx = r & np.uint32(0xFF)
        rabs = (r >> np.uint32(9)) & np.uint32(0x007FFFFF)
        x = _F32(_F32(rabs) * wi[idx]) * (one - two * _F32((r >> np.uint32(8)) & np.uint32(1)))
        if rabs < ki[idx]:
            return x
        if idx == 0:
            while True:
                xx = _F32(-inv_r_f * np.log1p(-_uniform(_word(k0, k1, ray, words, n))))
                yy = _F32(-np.log1p(-_uniform(_word(k0, k1, ray, words, n + 1))))
                n += 2
                if _F32(yy + yy) > _F32(xx * xx):
                    value = _F32(r_f + xx)
                    return -value if (rabs >> np.uint32(8)) & np.uint32(1) else value
        wedge = (fi[idx - 1] - fi[idx]) * _uniform(_word(k0, k1, ray, words, n)) + fi[idx]
        n += 1
        if wedge < np.exp(-0.5 * np.float64(x) * np.float64(x)):
            return x
        r = np.uint32(_word(k0, k1, ray, words, n))
        n += 1


@numba.njit(cache=True, nogil=True)
def _normals(k0, k1, rays, words, out, wi, ki, fi, r_f, inv_r_f):
    """numpy's float32 ziggurat on each ray's stream: the first word lands in its box 99.3 % of
    the time; the rest go on to _slow_normal."""
    one, two = _F32(1.0), _F32(2.0)
    for i in range(rays.shape[0]):
        r = words[NOISE, rays[i]]
        idx = r & np.uint32(0xFF)
        rabs = (r >> np.uint32(9)) & np.uint32(0x007FFFFF)
        if rabs < ki[idx]:
            out[i] = _F32(_F32(rabs) * wi[idx]) * (one - two * _F32((r >> np.uint32(8)) & np.uint32(1)))
        else:
            out[i] = _slow_normal(k0, k1, rays[i], words, r, wi, ki, fi, r_f, inv_r_f)


def normals(key: np.ndarray, rays: np.ndarray, words: np.ndarray) -> np.ndarray:
    """(len(rays),) float32 standard normals, one per ray, from its range-noise stream; `words`
    are ray_words of every ray."""
    out = np.empty(len(rays), _F32)
    _normals(key[0], key[1], np.ascontiguousarray(rays, np.int64), words, out, wi_float, ki_float,
             fi_float, ziggurat_nor_r_f, ziggurat_nor_inv_r_f)
    return out


def sweep_key(rng: np.random.Generator) -> np.ndarray:
    """The sweep's Philox key: the first two 32-bit words of its generator."""
    return rng.integers(0, 2**32, 2, dtype=np.uint32)
