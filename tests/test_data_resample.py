"""Arrival-time stamps (sensorless.data.resample.arrival_stamps) and reading the samples as uniform (time_from)."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.errors import TimestampError


def _arrival_log(tmp_path, rate=100.0, seconds=20.0, seed=0):
    """Samples taken at ``rate`` but stamped on arrival: delivered in packets every 40–170 ms, 0.3 ms apart."""
    import pandas as pd

    rng = np.random.default_rng(seed)
    n = int(rate * seconds)
    true_t = np.arange(n) / rate
    q = np.column_stack([np.sin(2 * true_t), 0.5 * np.cos(3 * true_t)])
    stamps, k = np.empty(n), 0
    clock = 1000.0
    while k < n:
        clock = max(clock + rng.uniform(0.04, 0.17), 1000.0 + true_t[k] + 0.01)
        m = int(np.sum((1000.0 + true_t[k:]) <= clock))  # everything sampled by now arrives in one burst
        m = max(m, 1)
        stamps[k:k + m] = clock + 3e-4 * np.arange(m)
        clock = stamps[k + m - 1]
        k += m
    path = tmp_path / "arrival.csv"
    pd.DataFrame({"time": stamps, "q_a": q[:, 0], "q_b": q[:, 1], "tau_a": q[:, 0], "tau_b": q[:, 1]}).to_csv(
        path, index=False)
    return path, true_t, q


def test_arrival_time_stamps_are_detected_and_read_as_uniform_with_time_from_rate(tmp_path):
    """Issue 40: stamps that are arrival times (bursts 0.3 ms apart after 40–170 ms gaps) were refused with a gap
    error only; the error now says what they are and `time_from="rate"` reads the samples as uniform."""
    from sensorless.data import prepare, read_trajectory
    from sensorless.data.limits import read_options

    path, true_t, q = _arrival_log(tmp_path)
    with pytest.raises(TimestampError, match=r"look like arrival times .* mean rate 99\.9\d* Hz.*`time_from='rate'`"):
        prepare(read_trajectory(path))
    with read_options(time_from="rate"):
        tr = read_trajectory(path)
    assert "mean rate of the stamps" in tr.units["t"]
    np.testing.assert_allclose(np.diff(tr.t), np.diff(tr.t)[0])
    assert abs(1 / np.diff(tr.t)[0] - 100.0) < 1.0  # the long-run rate of the arrivals
    np.testing.assert_array_equal(tr.q, q)
    with read_options(time_from="rate"):
        tr = read_trajectory(path, rate=100.0)
    np.testing.assert_allclose(tr.t, true_t)
