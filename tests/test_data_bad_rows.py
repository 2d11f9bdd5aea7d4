"""Corrupt rows at a log's start or end (sensorless.data.bad_rows): dropped with skip_bad_rows /
--skip-bad-rows and reported, an error that says how to drop them without it, and corruption in
the middle that stays an error naming its sample."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from sensorless.data import Trajectory, read_trajectory, validate_trajectory
from sensorless.data.bad_rows import max_edge_rows, scan_rows
from sensorless.errors import DataError, DataWarning, NonFiniteError, TimestampError
from sensorless_studies.simulation.log_faults import write_faulty_csv

N = 1000


def _log(n=N, seed=0):
    rng = np.random.default_rng(seed)
    t = 50.0 + np.arange(n) * 0.01
    q = np.column_stack([np.sin(t), 0.3 * np.cos(2 * t)]) + rng.normal(0, 1e-4, (n, 2))
    tau = np.column_stack([5 * np.sin(t), 2 * np.cos(t)]) + rng.normal(0, 0.05, (n, 2))
    return t, q, tau


def _traj(t, q, tau):
    return Trajectory(t=t, q=q, tau=tau, joint_names=("a", "b"), source="run.csv")


def _corrupt(t, q, tau, lead=9):
    """The reported file: ``lead`` leading rows with values up to 1e154 and time running backwards
    into the first real stamp, and a last row cut short (NaN in its missing fields)."""
    t, q, tau = t.copy(), q.copy(), tau.copy()
    t[:lead] = t[lead] + 0.3 * np.arange(lead, 0, -1)
    q[0:lead:2, 0] = 3e154
    tau[1:lead:3, 1] = -7e140
    q[-1, 1] = tau[-1] = np.nan
    return t, q, tau


def test_a_corrupt_prefix_and_cut_last_row_are_dropped_and_reported():
    t, q, tau = _log()
    bad = _corrupt(t, q, tau)
    with pytest.warns(DataWarning, match=r"run.csv: `skip_bad_rows=True` dropped 9 row\(s\) at the start \(samples 0..8") as w:
        out = validate_trajectory(_traj(*bad), skip_bad_rows=True)
    msg = str(w[0].message)
    assert "absurd values" in msg and "time going backwards" in msg and "1 row(s) at the end (sample 999" in msg
    assert len(out) == N - 10 and np.array_equal(out.t, t[9:-1]) and np.array_equal(out.q, q[9:-1])
    dropped = out.provenance["rows_dropped"]
    assert dropped["kept"] == [9, N - 2] and [(d["where"], d["first_sample"], d["last_sample"]) for d in
                                               dropped["dropped"]] == [("start", 0, 8), ("end", N - 1, N - 1)]


def test_without_the_option_the_error_says_how_to_drop_the_corrupt_rows():
    bad = _corrupt(*_log())
    with pytest.raises(DataError) as exc:
        validate_trajectory(_traj(*bad))
    msg = str(exc.value)
    assert "`skip_bad_rows=True`" in msg and "`trim='run.csv=abs:" in msg and "samples 0..8" in msg, msg
    window = msg.split("`trim='run.csv=")[1].split("'")[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the window suggested cuts them out without --skip-bad-rows
        out = validate_trajectory(_traj(*bad), trim=window)
    assert np.isfinite(out.q).all() and np.all(np.diff(out.t) > 0)


def test_a_trim_is_cut_before_the_time_axis_is_checked():
    t, q, tau = _log()
    t, q = t.copy(), q.copy()
    t[:5] = t[5] - 0.01 * np.array([1, 5, 3, 2, 4])[::-1] - 10  # stamps running backwards, well before the log
    q[:5] = np.nan
    with pytest.raises(DataError):
        validate_trajectory(_traj(t, q, tau))
    out = validate_trajectory(_traj(t, q, tau), trim=f"abs:{t[5]}:")
    assert len(out) == N - 5 and out.provenance["trim"]["samples"] == N - 5


def test_corruption_in_the_middle_stays_an_error_naming_the_sample():
    t, q, tau = _corrupt(*_log())
    q[600:610, 1] = np.nan  # more than a few isolated rows: a fault of the recording, not a glitch
    with pytest.raises(NonFiniteError, match=r"sample 600 .*`skip_bad_rows` drops only a corrupt prefix or suffix "
                                             r"of at most 50 rows \(it dropped 9 row\(s\) at the start.*middle"):
        with pytest.warns(DataWarning):
            validate_trajectory(_traj(t, q, tau), skip_bad_rows=True)
    t, q, tau = _log()
    t = t.copy()
    t[700:] -= 5.0  # two recordings concatenated: time restarts
    with pytest.raises(TimestampError, match=r"time goes backwards at sample 700.*only a corrupt prefix or suffix"):
        validate_trajectory(_traj(t, q, tau), skip_bad_rows=True)


def test_a_corrupt_piece_longer_than_the_edge_limit_is_not_dropped():
    t, q, tau = _log()
    q = q.copy()
    k = max_edge_rows(N) + 1
    q[:k, 0] = np.inf
    scan = scan_rows(t, [("q", q, ["a", "b"])])
    assert not scan.edges and scan.middle == f"sample {k - 1} (missing or non-finite values: 'q' column 'a' = inf)"
    with pytest.raises(NonFiniteError, match="sample 0 .*only a corrupt prefix or suffix"):
        validate_trajectory(_traj(t, q, tau), skip_bad_rows=True)


def test_repeated_stamps_at_the_start_are_dropped_and_a_clean_log_is_untouched():
    t, q, tau = _log()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = validate_trajectory(_traj(t, q, tau), skip_bad_rows=True)
    assert np.array_equal(out.t, t) and "rows_dropped" not in out.provenance
    t2 = t.copy()
    t2[:4] = t2[0]  # the logger's clock not yet running
    with pytest.warns(DataWarning, match=r"3 row\(s\) at the start \(samples 0..2: 3 with a repeated time stamp"):
        out = validate_trajectory(_traj(t2, q, tau), skip_bad_rows=True, allow_duplicate_times=True)
    assert len(out) == N - 3


def test_large_but_genuine_values_are_not_absurd():
    """A joint still for 97 % of the log that then moves, torques of a large arm, epoch stamps:
    nothing is corrupt."""
    t = 1.7e9 + np.arange(N) * 0.01
    q = np.zeros((N, 2))
    q[-30:, 0] = np.linspace(0, 3.0, 30)
    tau = np.column_stack([np.full(N, 900.0), np.where(np.arange(N) > 970, 2500.0, 0.0)])
    scan = scan_rows(t, [("q", q, ["a", "b"]), ("tau", tau, ["a", "b"])])
    assert not scan.edges and scan.middle is None


def test_csv_with_corrupt_leading_rows_and_a_last_row_cut_mid_number(tmp_path):
    t, q, tau = _log()
    table = pd.DataFrame({"time": t, "q_a": q[:, 0], "q_b": q[:, 1], "tau_a": tau[:, 0], "tau_b": tau[:, 1]})
    path = write_faulty_csv(table, tmp_path / "run.csv", leading=9, cut_after=3, seed=2)
    path.write_text(path.read_text() + "e-")  # the last field cut in its exponent: not a number
    with pytest.raises(DataError, match=r"non-numeric value .* at row 1008 .*`skip_bad_rows=True`"):
        read_trajectory(path)
    with pytest.warns(DataWarning, match=r"dropped 9 row\(s\) at the start .* and 1 row\(s\) at the end \(sample 1008"):
        out = read_trajectory(path, skip_bad_rows=True)
    assert len(out) == N - 1 and np.allclose(out.q, q[:-1]) and np.allclose(out.t, t[:-1])


def test_isolated_garbage_rows_anywhere_are_dropped_each_named(tmp_path):
    """Issue 40: a first row written at t = 0 before the logger's clock ran (a 3048 s gap was kept), and
    isolated garbage rows in the middle (a row cut short, an absurd value, a stamp out of order): all dropped
    by --skip-bad-rows, every one named; without it the error names the first."""
    t, q, tau = _log()
    t, q, tau = t + 3000.0, q.copy(), tau.copy()
    t[0] = 0.0
    q[0] = 0.0
    q[300, 1] = np.nan
    tau[555, 0] = 4e150
    t[700] = t[700] + 7.3  # a stamp out of order, its neighbours continue the clock
    table = pd.DataFrame({"time": t, "q_a": q[:, 0], "q_b": q[:, 1], "tau_a": tau[:, 0], "tau_b": tau[:, 1]})
    path = tmp_path / "run.csv"
    table.to_csv(path, index=False)
    with pytest.raises(DataError):
        read_trajectory(path)
    with pytest.warns(DataWarning) as w:
        out = read_trajectory(path, skip_bad_rows=True)
    msg = " ".join(str(x.message) for x in w)
    assert "1 row(s) at the start (sample 0: 1 with a stamp off the clock" in msg, msg
    for row, why in ((300, "non-finite"), (555, "absurd values"), (700, "a stamp out of order")):
        assert f"sample {row}: " in msg and why in msg, (row, msg)
    keep = np.setdiff1d(np.arange(1, N), [300, 555, 700])
    assert len(out) == len(keep) and np.array_equal(out.t, t[keep]) and np.allclose(out.q, q[keep])
    assert [d["sample"] for d in out.provenance["rows_dropped"]["isolated"]] == [300, 555, 700]
    assert np.max(np.diff(out.t)) < 0.05
