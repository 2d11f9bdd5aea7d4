"""Savitzky–Golay coefficients and filter, computed as :mod:`scipy.signal` computes them.

Why not ``scipy.signal.savgol_*``: importing :mod:`scipy.signal` costs 0.6–0.8 s on SciPy 1.17
(cumulative in ``python -X importtime`` of ``identify --method ols``: it parses ~650 docstrings and
pulls in scipy.stats), a third of that command's wall time on a 600-sample log, whose preprocessing
needs only these two functions. The same arithmetic here needs only :func:`numpy.linalg.lstsq` and
:func:`.window_filters.convolve_same` (SciPy's ``ndimage.convolve1d`` for an even window). The
coefficients use the same LAPACK driver (gelsd), cut-offs and operation order as SciPy (which calls
scipy.linalg.lstsq), so they equal SciPy's; the filter adds its taps in another order (equal to
rounding). tests/test_data_savgol.py checks both against SciPy, the oracle.

Coefficients: fit a polynomial of degree p to the window samples at offsets
t_k = k − pos (k = 0..w−1): c = A⁺ e_d · d!/δᵈ with A_jk = t_kʲ (j = 0..p), the minimum-norm
least-squares solution, so that c·x is the d-th derivative of the fit at ``pos``.
Filter (``mode="interp"`` only): convolve with the centred coefficients; the first/last
⌊w/2⌋ outputs are the d-th derivative of the degree-p polyfit of the first/last window,
evaluated at those samples.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["savgol_coeffs", "savgol_filter"]


def _lstsq(a: np.ndarray, b: np.ndarray, rcond: float) -> tuple[np.ndarray, int]:
    """Minimum-norm least squares by LAPACK gelsd, singular values < rcond·σ_max dropped (as scipy.linalg.lstsq)."""
    c, _, rank, _ = np.linalg.lstsq(a, b, rcond=rcond)
    return c, rank


def savgol_coeffs(window: int, polyorder: int, deriv: int = 0, delta: float = 1.0, pos: float | None = None,
                  use: str = "conv") -> np.ndarray:
    """FIR weights of the Savitzky–Golay fit of degree ``polyorder`` over ``window`` samples spaced
    ``delta`` apart: the ``deriv``-th derivative of the fit at ``pos`` (default: the window centre).
    ``use="dot"`` orders them oldest sample first (dot with the window), ``"conv"`` reversed."""
    if polyorder >= window:
        raise ValueError("polyorder must be less than window_length.")
    halflen, rem = divmod(window, 2)
    if pos is None:
        pos = halflen - 0.5 if rem == 0 else halflen
    if not 0 <= pos < window:
        raise ValueError("pos must be nonnegative and less than window_length.")
    if use not in ("conv", "dot"):
        raise ValueError("`use` must be 'conv' or 'dot'")
    if deriv > polyorder:
        return np.zeros(window)
    x = np.arange(-pos, window - pos, dtype=np.float64)
    if use == "conv":
        x = np.flip(x)
    A = x ** np.arange(polyorder + 1, dtype=np.float64).reshape(-1, 1)
    y = np.zeros(polyorder + 1)
    y[deriv] = (float(math.factorial(deriv)) if deriv < 171 else np.inf) / (delta**deriv)
    coeffs, _ = _lstsq(A, y, np.finfo(np.float64).eps * max(A.shape))
    return coeffs


def _polyfit(t: np.ndarray, y: np.ndarray, deg: int) -> np.ndarray:
    """Columns of ``y`` (n, m) fitted by polynomials of degree ``deg`` in ``t``, highest power first
    (numpy.polyfit's column scaling and cut-off, as SciPy's edge fit)."""
    lhs = t[:, None] ** np.flip(np.arange(deg + 1, dtype=t.dtype))[None, :]
    scale = np.sqrt(np.sum(lhs * lhs, axis=0))
    lhs /= scale
    c, rank = _lstsq(lhs, y, t.shape[0] * np.finfo(t.dtype).eps)
    if rank != deg + 1:
        import warnings

        warnings.warn("Polyfit may be poorly conditioned", np.exceptions.RankWarning, stacklevel=3)
    return (c.T / scale).T


def _polyder(p: np.ndarray, m: int) -> np.ndarray:
    """``m``-th derivative of the polynomials in the columns of ``p`` (highest power first)."""
    if m == 0:
        return p
    n = p.shape[0]
    if n <= m:
        return np.zeros_like(p[:1])
    dp = np.array(p[:-m], copy=True)
    for k in range(m):
        dp *= np.arange(n - k - 1, m - k - 1, -1, dtype=p.dtype).reshape((n - m,) + (1,) * (p.ndim - 1))
    return dp


def _fit_edge(x, start, stop, lo, hi, axis, polyorder, deriv, delta, y) -> None:
    """y[lo:hi] along ``axis`` = the ``deriv``-th derivative of the fit of x[start:stop]."""
    sl = [slice(None)] * x.ndim
    sl[axis] = slice(start, stop)
    edge = np.swapaxes(x[tuple(sl)], axis, 0)
    edge = edge.reshape(edge.shape[0], -1)
    p = _polyder(_polyfit(np.arange(0, stop - start, dtype=x.dtype), edge, polyorder), deriv)
    i = np.arange(lo - start, hi - start, dtype=p.dtype).reshape(-1, 1)
    v = np.zeros_like(i)
    for j in range(p.shape[0]):  # Horner, as np.polyval
        v = v * i + p[j, ...]
    v = v / (delta**deriv)
    shp = list(y.shape)
    shp[0], shp[axis] = shp[axis], shp[0]
    sl[axis] = slice(lo, hi)
    y[tuple(sl)] = np.swapaxes(v.reshape(hi - lo, *shp[1:]), 0, axis)


def savgol_filter(x, window: int, polyorder: int, deriv: int = 0, delta: float = 1.0, axis: int = 0,
                  mode: str = "interp") -> np.ndarray:
    """Savitzky–Golay smoothing (``deriv=0``) or ``deriv``-th derivative of ``x`` along ``axis``,
    with SciPy's ``mode="interp"`` edges (the only mode). Needs ``window <= x.shape[axis]``."""
    if mode != "interp":
        raise ValueError(f"only mode='interp' is implemented, got {mode!r}")
    x = np.asarray(x)
    if x.dtype != np.float64 and x.dtype != np.float32:
        x = x.astype(np.float64)
    axis = axis % x.ndim
    coeffs = savgol_coeffs(window, polyorder, deriv=deriv, delta=delta)
    if window > x.shape[axis]:
        raise ValueError("If mode is 'interp', window_length must be less than or equal to the size of x.")
    if window % 2:
        from .window_filters import convolve_same

        y = convolve_same(x, coeffs, axis=axis).astype(x.dtype, copy=False)
    else:  # SciPy's centring of an even window
        from scipy.ndimage import convolve1d

        y = convolve1d(x, coeffs, axis=axis, mode="constant")
    half, n = window // 2, x.shape[axis]
    _fit_edge(x, 0, window, 0, half, axis, polyorder, deriv, delta, y)
    _fit_edge(x, n - window, n, n - half, n, axis, polyorder, deriv, delta, y)
    return y
