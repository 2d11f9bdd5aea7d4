"""sensorless.data.window_filters against scipy.ndimage (the oracle): the same centring, edges and
values, for odd and even windows, windows longer than the log, and any axis; a log past
NUMPY_MAX_ELEMENTS goes to SciPy itself."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.ndimage as nd

from sensorless.data.window_filters import convolve_same, running_max, running_min


@pytest.mark.parametrize("n", [1, 2, 7, 50, 333])
@pytest.mark.parametrize("size", [1, 2, 3, 4, 11, 40, 401])
def test_running_extrema_equal_scipy(n, size, rng):
    x = rng.normal(size=(n, 3))
    x[n // 2:, 1] = 0.0  # ties and plateaus
    for axis in (0, 1):
        a = x if axis == 0 else x.T
        np.testing.assert_array_equal(running_max(a, size, axis=axis), nd.maximum_filter1d(a, size, axis=axis, mode="nearest"))
        np.testing.assert_array_equal(running_min(a, size, axis=axis), nd.minimum_filter1d(a, size, axis=axis, mode="nearest"))


@pytest.mark.parametrize("n", [1, 5, 64, 1000])
@pytest.mark.parametrize("taps", [1, 3, 7, 31])
def test_convolution_equals_scipy(n, taps, rng):
    x = rng.normal(size=(n, 4))
    c = rng.normal(size=taps)  # not symmetric: the kernel's flip matters
    for axis in (0, 1):
        a = x if axis == 0 else x.T
        ref = nd.convolve1d(a, c, axis=axis, mode="constant")
        np.testing.assert_allclose(convolve_same(a, c, axis=axis), ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())
    with pytest.raises(ValueError, match="odd"):
        convolve_same(x, np.ones(4))


def test_a_long_log_goes_to_scipy(rng, monkeypatch):
    from sensorless.data import window_filters as wf

    x = rng.normal(size=(400, 3))
    c = rng.normal(size=5)
    small = wf.convolve_same(x, c), wf.running_max(x, 7), wf.running_min(x, 7)
    monkeypatch.setattr(wf, "NUMPY_MAX_ELEMENTS", 100)  # x is now "long"
    calls = []
    real = nd.convolve1d
    monkeypatch.setattr(nd, "convolve1d", lambda *a, **k: calls.append("convolve1d") or real(*a, **k))
    big = wf.convolve_same(x, c), wf.running_max(x, 7), wf.running_min(x, 7)
    assert calls == ["convolve1d"]
    np.testing.assert_allclose(big[0], small[0], rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(big[1], small[1])
    np.testing.assert_array_equal(big[2], small[2])
