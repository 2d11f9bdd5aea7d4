"""Sliding-window filters along the sample axis, in NumPy: what identify's preprocessing used from
:mod:`scipy.ndimage` (``convolve1d`` with ``mode="constant"``, ``maximum_filter1d`` and
``minimum_filter1d`` with ``mode="nearest"``), with the same centring and edges.

Why not always ``scipy.ndimage``: it is ~0.07 s of imports at every ``sensorless identify`` start, for
three one-line filters; on a short log (up to :data:`NUMPY_MAX_ELEMENTS` values) that import is most of
their cost and NumPy does them here. A longer log goes to SciPy, whose C loops are 2–4× faster than
these NumPy passes at 10⁶ samples, and whose import is then small beside the pass
(tests/test_data_window_filters.py checks both routes against SciPy, the oracle).

* Convolution: ``y[i] = Σ_k c[k] x[i + h − k]`` (``h = ⌊w/2⌋``, ``x`` zero outside the log), one
  multiply-add pass over the samples per tap: no (n × w) window matrix is formed.
* Running maximum/minimum over ``x[i − ⌊w/2⌋ … i − ⌊w/2⌋ + w − 1]``, the first/last sample repeated
  past the ends: van Herk / Gil–Werman, a prefix and a suffix extremum within blocks of ``w``
  samples, so the cost does not grow with ``w``; exact (no arithmetic).
"""

from __future__ import annotations

import numpy as np

__all__ = ["NUMPY_MAX_ELEMENTS", "convolve_same", "running_max", "running_min"]

NUMPY_MAX_ELEMENTS = 200_000  # larger inputs go to scipy.ndimage (module docstring)


def convolve_same(x: np.ndarray, coeffs: np.ndarray, axis: int = 0) -> np.ndarray:
    """``scipy.ndimage.convolve1d(x, coeffs, axis=axis, mode="constant")`` for an odd number of taps."""
    c = np.asarray(coeffs, dtype=float)
    w = len(c)
    if w % 2 != 1:
        raise ValueError(f"convolve_same needs an odd number of coefficients, got {w}")
    if np.size(x) > NUMPY_MAX_ELEMENTS:
        from scipy.ndimage import convolve1d

        return convolve1d(x, c, axis=axis, mode="constant")
    x = np.moveaxis(np.asarray(x), axis, 0)
    n, h = x.shape[0], w // 2
    xp = np.zeros((n + 2 * h, *x.shape[1:]), dtype=np.result_type(x.dtype, c.dtype))
    xp[h: h + n] = x
    y = np.zeros_like(xp[:n])
    for k in range(w):  # tap k multiplies x[i + h − k] = xp[i + 2h − k]
        y += c[k] * xp[2 * h - k: 2 * h - k + n]
    return np.moveaxis(y, 0, axis)


def _running(x: np.ndarray, size: int, axis: int, op) -> np.ndarray:
    w = int(size)
    if w < 1:
        raise ValueError(f"window size must be >= 1, got {size}")
    if np.size(x) > NUMPY_MAX_ELEMENTS:
        import scipy.ndimage as nd

        f = nd.maximum_filter1d if op is np.maximum else nd.minimum_filter1d
        return f(x, w, axis=axis, mode="nearest")
    x = np.moveaxis(np.asarray(x), axis, 0)
    n = x.shape[0]
    if w == 1 or n == 0:
        return np.moveaxis(x.copy(), 0, axis)
    left = w // 2
    m = -(-(n + w - 1) // w) * w  # padded length: whole blocks of w
    idx = np.clip(np.arange(m) - left, 0, n - 1)  # "nearest": the end samples repeated
    xp = x[idx]
    blocks = xp.reshape(m // w, w, *x.shape[1:])
    g = op.accumulate(blocks, axis=1).reshape(xp.shape)  # extremum from each block's start
    s = op.accumulate(blocks[:, ::-1], axis=1)[:, ::-1].reshape(xp.shape)  # … to each block's end
    # window [i, i + w − 1] (padded coordinates) spans at most two blocks: suffix at i, prefix at i + w − 1
    y = op(s[:n], g[w - 1: w - 1 + n])
    return np.moveaxis(y, 0, axis)


def running_max(x: np.ndarray, size: int, axis: int = 0) -> np.ndarray:
    """``scipy.ndimage.maximum_filter1d(x, size, axis=axis, mode="nearest")``."""
    return _running(x, size, axis, np.maximum)


def running_min(x: np.ndarray, size: int, axis: int = 0) -> np.ndarray:
    """``scipy.ndimage.minimum_filter1d(x, size, axis=axis, mode="nearest")``."""
    return _running(x, size, axis, np.minimum)
