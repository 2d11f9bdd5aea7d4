"""Whitespace text logs: one file for all signals or a folder of one file per signal, and
tick/time columns (sensorless.data.textlog, sensorless.data.timebase)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.data import read_trajectory
from sensorless.errors import DataError, DataWarning, TimestampError, UnitsError

NAMES = ("j1", "j2", "j3")


def _log(n: int = 400, k: int = 3, seed: int = 0):
    rng = np.random.default_rng(seed)
    ticks = 1_000 + 2 * np.arange(n)  # a 1 kHz controller logging every 2nd tick: 500 Hz
    t = ticks / 1000.0
    w = 2 * np.pi * rng.uniform(0.3, 1.0, k)
    q = 0.7 * np.sin(w * t[:, None])
    return ticks, t, q, 0.7 * w * np.cos(w * t[:, None]), rng.normal(size=(n, k))


def _write(path, ticks, val, header: str | None = "tick j1 j2 j3"):
    np.savetxt(path, np.column_stack([ticks, val]), fmt=["%d"] + ["%.17g"] * val.shape[1],
               header=header or "", comments="")


def _quiet(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        return read_trajectory(path, **kw)


def test_one_whitespace_file_with_a_tick_column(tmp_path):
    ticks, t, q, v, tau = _log()
    header = "tick " + " ".join(f"q_{j}" for j in NAMES) + " " + " ".join(f"dq_{j}" for j in NAMES) + " " + \
        " ".join(f"effort_{j}" for j in NAMES)
    np.savetxt(tmp_path / "run.dat", np.column_stack([ticks, q, v, tau]), fmt="%.17g", header=header, comments="")
    with pytest.raises(UnitsError, match=r"time column 'tick' counts controller ticks.*`time_unit='tick'` `rate=HZ`"):
        read_trajectory(tmp_path / "run.dat")
    tr = read_trajectory(tmp_path / "run.dat", time_unit="tick", rate=1000)
    assert tr.joint_names == NAMES and tr.rate == pytest.approx(500.0)
    np.testing.assert_array_equal(tr.t, t)
    np.testing.assert_array_equal(tr.v, v)
    np.testing.assert_array_equal(tr.tau, tau)


def test_an_integer_counter_under_a_time_name_is_refused_not_read_as_seconds(tmp_path):
    """A column named 't' that counts 1000, 1002, ...: read as seconds it is a 0.5 Hz log."""
    ticks, t, q, _, _ = _log()
    np.savetxt(tmp_path / "c.txt", np.column_stack([ticks, q]), fmt="%.17g", header="t q_a q_b q_c", comments="")
    with pytest.raises(UnitsError, match=r"time column 't' counts in whole steps.*`time_unit='tick'` `rate=HZ`"):
        read_trajectory(tmp_path / "c.txt")


def test_per_signal_folder_joins_on_ticks_and_names_unused_files(tmp_path):
    ticks, t, q, v, tau = _log()
    d = tmp_path / "run"
    d.mkdir()
    _write(d / "q.dat", ticks, q)
    _write(d / "qd.dat", ticks, v)
    _write(d / "torque.dat", ticks[5:], tau[5:])  # started 5 samples later
    _write(d / "temperature.dat", ticks, np.ones_like(q))
    with pytest.warns(DataWarning) as rec:
        tr = read_trajectory(d, time_unit="tick", rate=1000)
    msgs = [str(w.message) for w in rec]
    assert any("files not used: 'temperature.dat'" in m for m in msgs), msgs
    assert any("dropped the rows not in every file (5 of q.dat, 5 of qd.dat)" in m for m in msgs), msgs
    assert tr.joint_names == NAMES and len(tr) == len(ticks) - 5
    np.testing.assert_array_equal(tr.t, t[5:])
    np.testing.assert_array_equal(tr.q, q[5:])
    np.testing.assert_array_equal(tr.v, v[5:])
    np.testing.assert_array_equal(tr.tau, tau[5:])


def test_per_signal_folder_headerless_with_columns_naming_the_files(tmp_path):
    """No header: the first column is time; --columns names the files; the tick rule sees the values."""
    ticks, t, q, v, tau = _log()
    d = tmp_path / "run"
    d.mkdir()
    _write(d / "enc.txt", ticks, q, header=None)
    _write(d / "mot.txt", ticks, tau, header=None)
    with pytest.raises(DataError, match=r"no file of joint positions.*'enc', 'mot'.*`columns=\{'q': 'FILE'\}`"):
        read_trajectory(d)
    with pytest.raises(UnitsError, match=r"time column 'column 0' counts in whole steps.*`time_unit='tick'` `rate=HZ`"):
        read_trajectory(d, columns={"q": "enc", "tau": "mot.txt"})
    tr = read_trajectory(d, columns={"q": "enc", "tau": "mot.txt"}, time_unit="tick", rate=1000)
    np.testing.assert_array_equal(tr.t, t)
    np.testing.assert_array_equal(tr.tau, tau)


def test_per_signal_files_that_share_no_stamps_are_refused(tmp_path):
    ticks, t, q, _, tau = _log()
    d = tmp_path / "run"
    d.mkdir()
    _write(d / "q.dat", ticks, q)
    _write(d / "tau.dat", ticks + 1, tau)  # another clock
    with pytest.raises(TimestampError, match=r"do not share their time stamps.*q.dat: 400 rows"):
        read_trajectory(d, time_unit="tick", rate=1000)


def test_per_signal_files_with_different_joint_counts_are_refused(tmp_path):
    ticks, t, q, _, tau = _log()
    d = tmp_path / "run"
    d.mkdir()
    _write(d / "q.dat", ticks, q)
    _write(d / "tau.dat", ticks, tau[:, :2], header="tick j1 j2")
    with pytest.raises(DataError, match=r"q.dat has 3 joint columns but tau.dat \(2\)"):
        read_trajectory(d, time_unit="tick", rate=1000)


def test_tick_unit_needs_a_rate_and_a_time_column(tmp_path):
    ticks, t, q, _, _ = _log()
    _write(tmp_path / "a.dat", ticks, q)
    with pytest.raises(DataError, match=r"`time_unit='tick'` needs the tick rate: `rate=HZ`"):
        read_trajectory(tmp_path / "a.dat", time_unit="tick")
    np.savetxt(tmp_path / "b.dat", q, header="q_a q_b q_c", comments="")
    with pytest.raises(DataError, match=r"`time_unit='tick'`: the log has no time/tick column"):
        _quiet(tmp_path / "b.dat", time_unit="tick", rate=1000)


def test_cli_tick_options_are_recorded_and_predict_reuses_them(tmp_path, ur5):
    """identify --time-unit tick --rate 1000 on a folder; predict on it without any option."""
    import json

    from sensorless.cli import app
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    tr = synthetic_trajectory(perturbed_truth(ur5, rng=1), random_fourier(ur5, rng=2).sample(500.0, 3.0),
                              noise_std=0.02, rng=3)
    ticks = 7 + 2 * np.arange(len(tr))
    d = tmp_path / "run"
    d.mkdir()
    header = "tick " + " ".join(tr.joint_names)
    for name, val in (("q", tr.q), ("v", tr.v), ("tau", tr.tau)):
        _write(d / f"{name}.dat", ticks, val, header=header)
    run = CliRunner().invoke
    r = run(app, ["identify", "--robot", "ur5", "--data", str(d), "--method", "ols", "--no-plot", "--joint-terms",
                  "fv,fc", "--time-unit", "tick", "--rate", "1000", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    prep = json.loads((tmp_path / "m" / "result.json").read_text())["settings"]["preprocessing"]
    assert prep["time_unit"] == "tick" and prep["rate"] == 1000
    r = run(app, ["predict", "--robot", "ur5", "--model", str(tmp_path / "m"), "--data", str(d),
                  "--out", str(tmp_path / "p.npz")])
    assert r.exit_code == 0, r.output
    with np.load(tmp_path / "p.npz") as z:
        t = z["times"] if "times" in z.files else z["t"]
    np.testing.assert_allclose(np.diff(t), 0.002, rtol=1e-9)


def test_tick_tab_tab_value_files_have_no_phantom_column(tmp_path):
    """Issue 40: per-signal files written tick<TAB><TAB>value… were read with an all-NaN first joint column."""
    ticks, t, q, v, tau = _log()
    d = tmp_path / "run"
    d.mkdir()
    for name, val in (("q.dat", q), ("tau.dat", tau)):
        (d / name).write_text("".join(f"{k}\t\t" + "\t".join(f"{x:.17g}" for x in row) + "\n"
                                      for k, row in zip(ticks, val)))
    tr = read_trajectory(d, time_unit="tick", rate=1000)
    assert tr.q.shape == q.shape
    np.testing.assert_array_equal(tr.q, q)
    np.testing.assert_array_equal(tr.tau, tau)


def test_a_field_composed_of_columns_of_several_files_and_contact_flags_from_a_file(tmp_path):
    """Issue 40: a passive slider whose position another sensor logs: q = the height sensor's column 1, then
    columns 1 and 2 of the joint encoders' file (in that order); the contact flags from their own file."""
    ticks, t, q, v, tau = _log()
    d = tmp_path / "leg"
    d.mkdir()
    height = np.column_stack([q[:, 0], 5.0 + q[:, 0]])  # the slider, and a second sensor no field uses
    joints = np.column_stack([q[:, 1], q[:, 2], np.zeros(len(q))])
    _write(d / "height_sensors.dat", ticks, height, header=None)
    _write(d / "joint_positions.dat", ticks, joints, header=None)
    _write(d / "torques.dat", ticks, tau, header=None)
    flags = (np.sin(t) > 0).astype(float)[:, None]
    _write(d / "feet.dat", ticks[5:], flags[5:], header=None)  # starts later: joined on the shared ticks
    cols = {"q": "height_sensors.dat:1,joint_positions.dat:1:3", "tau": "torques", "contact": "feet.dat"}
    tr = _quiet(d, columns=cols, time_unit="tick", rate=1000)
    np.testing.assert_array_equal(tr.q, q[5:])
    np.testing.assert_array_equal(tr.tau, tau[5:])
    np.testing.assert_array_equal(tr.extras["contact"], flags[5:].astype(bool))
    with pytest.raises(DataError, match=r"'joint_positions.dat:1:x' is not FILE, FILE:K or FILE:A:B"):
        read_trajectory(d, columns={**cols, "q": "height_sensors.dat:1,joint_positions.dat:1:x"})
    with pytest.raises(DataError, match=r"columns 2:9 \(for 'q'\) are beyond the file's 4 columns"):
        read_trajectory(d, columns={**cols, "q": "joint_positions.dat:2:9"}, time_unit="tick", rate=1000)
