"""sensorless.data.savgol against scipy.signal (the oracle): coefficients and ``mode="interp"`` filter
equal to 1e-12 relative (the filter: to 1e-11 of Σ|c_k x_k|, the size of the sum before it cancels:
SciPy adds paired taps, NumPy one tap at a time; on the worst case, a 5th derivative of a 43-sample
window, an exact rational sum sides with NumPy) over windows 5..51, polyorders 0..5, every derivative, sample periods down to
1e-3 s, centred and causal positions, 1-D/2-D/3-D inputs along axis 0 and 1, inputs as short as the window;
and ``sensorless identify --method ols`` no longer imports scipy.signal (the reason the module exists)."""

from __future__ import annotations


import numpy as np
import pytest
import scipy.ndimage as nd
import scipy.signal as ss

from conftest import identify_imports

from sensorless.data.savgol import savgol_coeffs, savgol_filter

TOL = 1e-12


def _rel(a, b) -> float:
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


@pytest.mark.parametrize("window", range(5, 52))
def test_coefficients_equal_scipys(window):
    for p in range(min(6, window)):
        for d in range(p + 2):  # d = p + 1: the all-zero weights
            for delta in (1.0, 1e-3, 0.37):
                for pos in (None, window - 1, 0, window // 3):
                    for use in ("conv", "dot"):
                        ref = ss.savgol_coeffs(window, p, deriv=d, delta=delta, pos=pos, use=use)
                        assert _rel(savgol_coeffs(window, p, deriv=d, delta=delta, pos=pos, use=use), ref) <= TOL, \
                            (window, p, d, delta, pos, use)


def test_even_window_and_bad_arguments_as_scipy():
    assert _rel(savgol_coeffs(6, 2, deriv=1), ss.savgol_coeffs(6, 2, deriv=1)) <= TOL  # pos = 2.5
    for args, kw in (((5, 5), {}), ((5, 2), {"pos": 5}), ((5, 2), {"use": "both"})):
        with pytest.raises(ValueError):
            savgol_coeffs(*args, **kw)
        with pytest.raises(ValueError):
            ss.savgol_coeffs(*args, **kw)
    with pytest.raises(ValueError, match="window_length must be less"):
        savgol_filter(np.zeros(10), 11, 3)
    with pytest.raises(ValueError, match="only mode='interp'"):
        savgol_filter(np.zeros(20), 11, 3, mode="mirror")


@pytest.mark.parametrize("window", range(5, 52, 2))
def test_interp_filter_equals_scipys(window):
    rng = np.random.default_rng(window)
    shapes = (((window,), 0), ((3 * window + 4,), 0), ((2 * window + 7, 3), 0), ((4, window + 9), 1),
              ((window, 2), 0), ((3, window), 1), ((2, 2 * window, 3), 1))
    for p in range(min(6, window)):
        for d in range(p + 1):
            for delta in (1.0, 1e-3):
                for shape, axis in shapes:
                    x = rng.normal(size=shape).cumsum(axis=axis) * 50.0
                    ref = ss.savgol_filter(x, window, p, deriv=d, delta=delta, axis=axis, mode="interp")
                    got = savgol_filter(x, window, p, deriv=d, delta=delta, axis=axis)
                    c = np.abs(ss.savgol_coeffs(window, p, deriv=d, delta=delta))
                    size = max(np.abs(ref).max(), nd.convolve1d(np.abs(x), c, axis=axis, mode="constant").max())
                    assert np.abs(got - ref).max() <= 10 * TOL * size, (window, p, d, delta, shape, axis)


def test_integer_input_and_negative_axis_as_scipy():
    x = np.arange(60).reshape(20, 3) ** 2
    assert _rel(savgol_filter(x, 7, 2, deriv=1, axis=-2), ss.savgol_filter(x, 7, 2, deriv=1, axis=-2)) <= TOL


def test_the_filter_is_exact_on_polynomials_of_its_degree():
    """Property independent of SciPy: a cubic and its derivatives are reproduced, edges included."""
    t = np.arange(40) * 0.01
    q = 2.0 - t + 3.0 * t**2 - 5.0 * t**3
    for d, ref in enumerate((q, -1.0 + 6.0 * t - 15.0 * t**2, 6.0 - 30.0 * t)):
        assert np.allclose(savgol_filter(q, 11, 3, deriv=d, delta=0.01), ref, rtol=0, atol=1e-9)


@pytest.mark.parametrize("causal", [False, True])
def test_savitzky_golay_class_equals_the_scipy_route(causal):
    """data.filtering.SavitzkyGolay (centred and causal, as the preprocessing and the streamed path use it)
    against the route it replaced: scipy's coefficients, interp filter and causal warm-up head."""
    from sensorless.data.filtering import SavitzkyGolay

    rng = np.random.default_rng(3)
    x = rng.normal(size=(90, 4)).cumsum(axis=0)
    for w, p, dt in ((11, 3, 0.01), (21, 3, 1e-3), (5, 2, 0.5)):
        sg = SavitzkyGolay(w, p, dt, causal=causal)
        for d in range(p + 1):
            c = ss.savgol_coeffs(w, p, deriv=d, delta=dt, pos=w - 1 if causal else None, use="dot")
            assert _rel(sg.coeffs[d], c) <= TOL
            if causal:
                ref = np.empty_like(x)
                ref[w - 1:] = np.lib.stride_tricks.sliding_window_view(x, w, axis=0) @ c
                ref[: w - 1] = ss.savgol_filter(x[:w], w, p, deriv=d, delta=dt, axis=0, mode="interp")[: w - 1]
            else:
                ref = ss.savgol_filter(x, w, p, deriv=d, delta=dt, axis=0, mode="interp")
            assert _rel(sg.apply(x, d), ref) <= TOL, (w, p, d)


def test_identify_ols_does_not_import_scipy_signal(ur5, tmp_path):
    """`sensorless identify --method ols` on a small UR5 log runs without importing scipy.signal
    (0.6–0.8 s of imports on SciPy 1.17) and still derives nothing with it: the log's noise and rest
    detection go through sensorless.data.savgol."""
    out, imported = identify_imports(ur5, tmp_path, ["--method", "ols"], ["scipy.signal", "sensorless.data.savgol"])
    assert (out / "result.json").exists()
    assert imported == {"scipy.signal": False, "sensorless.data.savgol": True}
