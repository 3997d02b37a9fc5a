"""numpy's float32 standard normals, the same numbers from the same generator state, in half the
time.

`Generator.standard_normal(n, dtype=np.float32)` runs the float32 ziggurat of numpy's
distributions.c, one 32-bit word of the bit generator per draw (99.3 % of them; the rest take a
few more words), and spends most of its time on the draw's sign, a branch the CPU cannot
predict. `standard_normal` here takes the same words in bulk (`Generator.integers` over the full
uint32 range hands out exactly the bit generator's next 32-bit words) and runs the same
ziggurat, with numpy's tables (as numba ports them), in a compiled loop that sets the sign
without a branch. It never takes a word numpy would not: a draw that needs more words than are
left waits for the next batch, so the generator ends where numpy's own call leaves it.
"""

from __future__ import annotations

import numba
import numpy as np
from numba.np.random._constants import fi_float, ki_float, wi_float, ziggurat_nor_inv_r_f, ziggurat_nor_r_f

_F32 = np.float32


@numba.njit(cache=True, nogil=True)
def _uniform(word):
    """numpy's next_float: the word's top 24 bits over 2 ** 24."""
    return _F32(_F32(word >> np.uint32(8)) * _F32(1.0) / _F32(16777216.0))


@numba.njit(cache=True, nogil=True)
def _slow(words, p, rabs, idx, x, fi, r_f, inv_r_f):
    """The ziggurat's rare branches for a draw whose first word missed its box (numpy's
    random_standard_normal_f, same operations and precisions): the tail beyond r for box 0,
    else the wedge test. Returns (status, value, next word): status 1 accepts the value,
    0 rejects the draw (it starts over on the next word), -1 ran out of words."""
    m = words.shape[0]
    if idx == 0:
        while p + 2 <= m:
            xx = _F32(-inv_r_f * np.log1p(-_uniform(words[p])))
            yy = _F32(-np.log1p(-_uniform(words[p + 1])))
            p += 2
            if _F32(yy + yy) > _F32(xx * xx):
                value = _F32(r_f + xx)
                return 1, -value if (rabs >> np.uint32(8)) & np.uint32(1) else value, p
        return -1, x, p
    if p >= m:
        return -1, x, p
    wedge = (fi[idx - 1] - fi[idx]) * _uniform(words[p]) + fi[idx]
    return (1 if wedge < np.exp(-0.5 * np.float64(x) * np.float64(x)) else 0), x, p + 1


@numba.njit(cache=True, nogil=True)
def _fill(words, out, k, wi, ki, fi, r_f, inv_r_f):
    """Draws out[k:] from `words`; returns how many of `out` are drawn and how many words they
    took (a draw the words end inside is left for the next batch)."""
    m = words.shape[0]
    p = 0
    one, two = _F32(1.0), _F32(2.0)
    while k < out.shape[0]:
        start = p
        status = 0
        x = _F32(0.0)
        while status == 0:
            if p >= m:
                return k, start
            r = words[p]
            p += 1
            idx = r & np.uint32(0xFF)
            rabs = (r >> np.uint32(9)) & np.uint32(0x007FFFFF)
            x = _F32(_F32(rabs) * wi[idx]) * (one - two * _F32((r >> np.uint32(8)) & np.uint32(1)))
            if rabs < ki[idx]:
                status = 1
            else:
                status, x, p = _slow(words, p, rabs, idx, x, fi, r_f, inv_r_f)
        if status < 0:
            return k, start
        out[k] = x
        k += 1
    return k, p


def standard_normal(rng: np.random.Generator, n: int) -> np.ndarray:
    """rng.standard_normal(n, dtype=np.float32), bit for bit, leaving `rng` in the same state.
    Each batch draws one word per draw still to make, plus the words a draw left unfinished
    needs at least one more of, so no batch reaches past what numpy would take."""
    out = np.empty(n, _F32)
    words = rng.integers(0, 2**32, n, dtype=np.uint32)
    k = 0
    while True:
        k, used = _fill(words, out, k, wi_float, ki_float, fi_float, ziggurat_nor_r_f, ziggurat_nor_inv_r_f)
        if k == n:
            return out
        words = np.concatenate([words[used:], rng.integers(0, 2**32, n - k, dtype=np.uint32)])
