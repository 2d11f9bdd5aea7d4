"""The streamed log's chunk derivative inside the log (data.streamed_log.ValidCorrelation, by FFT) is the
Savitzky–Golay derivative's plain correlation to rounding, for windows and chunk lengths of any size."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.data.filtering import SavitzkyGolay
from sensorless.data.streamed_log import ValidCorrelation


@pytest.mark.parametrize("window,n", [(11, 11), (11, 400), (201, 2449), (201, 2048 + 201), (51, 777)])
def test_fft_correlation_equals_the_direct_sum(window, n):
    rng = np.random.default_rng(window + n)
    t = np.arange(n) * 1e-3
    x = np.column_stack([np.sin(2 * np.pi * 0.3 * t + k) + 1e-3 * rng.standard_normal(n) for k in range(3)])
    sg = SavitzkyGolay(window, 3, 1e-3)
    c = sg.coeffs[1]
    direct = np.lib.stride_tricks.sliding_window_view(x, window, axis=0) @ c
    corr = ValidCorrelation(c)
    got = corr(x)
    assert got.shape == (n - window + 1, 3)
    assert np.abs(got - direct).max() <= 1e-12 * np.abs(direct).max()
    inside = sg.apply(x, 1)[window // 2 : n - window // 2]  # the filter away from the edge fits
    assert np.abs(got - inside).max() <= 1e-12 * np.abs(inside).max()
    assert np.array_equal(corr(x), got)  # the coefficient spectrum is cached per size
