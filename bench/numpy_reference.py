"""Vectorized NumPy reference for batch PI (Prandtl–Ishlinskii) RMSE — the benchmark baseline.

Same model and cost as ``piezohyst.batch.batch_rmse("pi", params, v, target, dims=[n, 0])``
(docs/spec.md §2.1)::

    z_r(k) = max(v(k) - r, min(v(k) + r, z_r(k-1))),   z_r(-1) = 0
    y(k)   = p0*v(k) + sum_i w_i z_{r_i}(k)
    RMSE   = sqrt(mean((y - target)^2))

How it is made fast (it is a baseline, so it should be a good one):

* All ``S`` parameter sets and ``n`` operators advance together as ``(S, n)`` arrays; the
  only Python loop is over time, and it can't be avoided because the play operator is a
  recurrence.
* The time loop runs in blocks of ``B`` samples, with ``B`` chosen so that the block's three
  ``(B, S, n)`` buffers fit in about ``budget`` bytes (cache sized). The parts that are not
  recurrent are whole-block array operations: the band edges ``v(k) -/+ r`` are computed
  before the loop, and the weighted sum (one ``einsum``), ``p0*v``, the error and its square
  are computed after it.
* Per sample, the recurrence costs two ufunc calls, ``np.minimum`` then ``np.maximum``, in
  the spec's (docs/spec.md) order. They write into views that were made before the loop, so the loop
  allocates nothing. The play outputs ``z`` are therefore bit-identical to a scalar
  evaluation. ``y`` and the RMSE differ from piezohyst only by the rounding of the sums
  (the summation order is different), which is about 1e-15 relative.
* Single-threaded: only ufuncs and ``einsum`` without ``optimize`` are used, so there are no
  BLAS calls and no threads.
"""

from __future__ import annotations

import numpy as np

__all__ = ["block_size", "pi_batch_rmse", "pi_batch_rmse_per_step"]

DEFAULT_BUDGET = 512 * 1024  # bytes for the three (B, S, n) block buffers


def block_size(S: int, n: int, N: int, budget: int = DEFAULT_BUDGET) -> int:
    """Samples per block so that lo, hi and Z (each ``(B, S, n)`` float64) fit in ``budget``."""
    return int(max(1, min(N, budget // (3 * 8 * max(1, S * n)))))


def pi_batch_rmse(params, v, target, n: int, *, budget: int = DEFAULT_BUDGET) -> np.ndarray:
    """``(S,)`` RMSE of ``S`` classical-PI parameter rows ``[p0, r_1..r_n, w_1..w_n]``."""
    params = np.asarray(params, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    S = params.shape[0]
    N = v.shape[0]
    if params.shape[1] != 1 + 2 * n:
        raise ValueError(f"params has {params.shape[1]} columns, expected {1 + 2 * n}")
    p0 = np.ascontiguousarray(params[:, 0])
    r = np.ascontiguousarray(params[:, 1 : 1 + n])
    w = np.ascontiguousarray(params[:, 1 + n : 1 + 2 * n])

    B = block_size(S, n, N, budget)
    z = np.zeros((S, n))  # z(-1) = 0
    lo = np.empty((B, S, n))  # v(k) - r
    hi = np.empty((B, S, n))  # v(k) + r
    Z = np.empty((B, S, n))  # z(k) for the block
    lo_rows, hi_rows, z_rows = list(lo), list(hi), list(Z)  # views made once
    Y = np.empty((B, S))
    sse = np.zeros(S)
    minimum, maximum = np.minimum, np.maximum

    for k0 in range(0, N, B):
        vb = v[k0 : k0 + B]
        b = vb.shape[0]
        vcol = vb[:, None, None]
        np.subtract(vcol, r, out=lo[:b])
        np.add(vcol, r, out=hi[:b])
        prev = z
        for lk, hk, zk in zip(lo_rows[:b], hi_rows[:b], z_rows[:b], strict=False):
            minimum(prev, hk, out=zk)  # min(v + r, z(k-1))
            maximum(zk, lk, out=zk)  # max(v - r, .)
            prev = zk
        z[...] = prev
        y = Y[:b]
        np.einsum("bij,ij->bi", Z[:b], w, out=y)  # sum_i w_i z_i(k)
        y += np.multiply.outer(vb, p0)
        y -= target[k0 : k0 + b, None]
        y *= y
        sse += y.sum(axis=0)
    return np.sqrt(sse / N)


def pi_batch_rmse_scalar(params, v, target, n: int) -> np.ndarray:
    """Plain-Python loop version (slow; for cross-checking the vectorized one on small cases)."""
    params = np.asarray(params, dtype=np.float64)
    out = np.empty(params.shape[0])
    for s, row in enumerate(params):
        p0, r, w = row[0], row[1 : 1 + n], row[1 + n :]
        z = [0.0] * n
        sse = 0.0
        for vk, tk in zip(v.tolist(), target.tolist(), strict=False):
            y = p0 * vk
            for i in range(n):
                z[i] = max(vk - r[i], min(vk + r[i], z[i]))
                y += w[i] * z[i]
            sse += (y - tk) ** 2
        out[s] = np.sqrt(sse / len(v))
    return out


def pi_batch_rmse_per_step(params, v, target, n: int) -> np.ndarray:
    """The straightforward form of the reference: per sample, the whole ``(S, n)`` play
    update and the weighted sum as array operations (what a NumPy user writes first).
    Same model; no blocking of the non-recurrent parts."""
    params = np.asarray(params, dtype=np.float64)
    p0 = params[:, 0]
    r = params[:, 1 : 1 + n]
    w = params[:, 1 + n : 1 + 2 * n]
    z = np.zeros_like(r)
    lo = np.empty_like(r)
    hi = np.empty_like(r)
    sse = np.zeros(params.shape[0])
    for vk, tk in zip(v.tolist(), target.tolist(), strict=False):
        np.subtract(vk, r, out=lo)
        np.add(vk, r, out=hi)
        np.minimum(z, hi, out=z)
        np.maximum(z, lo, out=z)
        e = p0 * vk + np.einsum("ij,ij->i", w, z) - tk
        sse += e * e
    return np.sqrt(sse / len(v))
