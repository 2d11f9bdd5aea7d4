"""Tests of sensorless.data: validation, readers, filtering, resampling."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sensorless.data import (
    SavitzkyGolay,
    Trajectory,
    butter_lowpass,
    decimate,
    lowpass,
    read_trajectory,
    resample_uniform,
    savgol_derivatives,
    trim,
    validate_trajectory,
    write_npz,
)
from sensorless.errors import TooFewSamplesError
from sensorless.errors import (
    DataError,
    ExcitationError,
    JointNameError,
    NonFiniteError,
    ShapeMismatchError,
    TimestampError,
    UnitsError,
)

REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"
KUKA_NPZ = REALDATA / "kuka_lwr4_flobaroid" / "data" / "KUKA" / "HW" / "measurements_1.npz"
KUKA_URDF = REALDATA / "kuka_lwr4_flobaroid" / "model" / "kuka_lwr4.urdf"
DVRK_CSV = REALDATA / "dvrk_psm_wpi" / "data" / "psm" / "measured_trajectory" / "one_results.csv"

NAMES = tuple(f"j{i}" for i in range(7))


def make_traj(n: int = 400, rate: float = 200.0, names=NAMES, seed: int = 0) -> Trajectory:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    k = len(names)
    f = rng.uniform(0.2, 1.0, k)
    ph = rng.uniform(0, np.pi, k)
    w = 2 * np.pi * f
    q = 0.8 * np.sin(w * t[:, None] + ph)
    v = 0.8 * w * np.cos(w * t[:, None] + ph)
    a = -(w**2) * q
    tau = rng.normal(size=(n, k))
    return Trajectory(t=t, q=q, joint_names=names, v=v, a=a, tau=tau, source="log.npz")


@pytest.fixture(scope="module")
def ur5():
    from sensorless.robot import load_robot

    return load_robot("ur5")


@pytest.fixture(scope="module")
def panda():
    from sensorless.robot import load_robot

    return load_robot("panda", lock_joints=["panda_finger_joint1", "panda_finger_joint2"])


# ---- validation ---------------------------------------------------------------------
def test_valid_trajectory_passes_unchanged():
    tr = make_traj()
    out = validate_trajectory(tr)
    assert out.joint_names == NAMES
    np.testing.assert_array_equal(out.q, tr.q)


def test_nan_in_tau_names_field_column_sample_and_count():
    tr = make_traj()
    tau = tr.tau.copy()
    tau[[120, 130], 2] = np.nan
    tau[140, 2] = np.inf
    tau[200, 5] = np.nan
    with pytest.raises(NonFiniteError) as exc:
        validate_trajectory(tr.with_(tau=tau))
    msg = str(exc.value)
    assert "'tau' column 'j2' has 3 non-finite values" in msg
    assert "first at sample 120 (t=0.600 s)" in msg
    assert msg.startswith("log.npz:") and exc.value.source == "log.npz"
    assert "1 other column" in msg


def test_nan_in_time_is_reported():
    tr = make_traj()
    t = tr.t.copy()
    t[7] = np.nan
    with pytest.raises(NonFiniteError, match=r"'t' has 1 non-finite values.*sample 7"):
        validate_trajectory(tr.with_(t=t))


def test_shape_mismatch_columns_and_rows():
    tr = make_traj()
    with pytest.raises(ShapeMismatchError, match="column count of 'tau' is 6 but there are 7 joint names"):
        validate_trajectory(tr.with_(tau=tr.tau[:, :6]))
    with pytest.raises(ShapeMismatchError, match="row count of 'v' is 399 but 't' has 400 samples"):
        validate_trajectory(tr.with_(v=tr.v[:-1]))
    with pytest.raises(ShapeMismatchError, match="'base_v' needs 6"):
        validate_trajectory(tr.with_(base_v=np.zeros((len(tr), 7))))


def test_duplicate_and_backwards_timestamps():
    tr = make_traj()
    t = tr.t.copy()
    t[5] = t[4]
    with pytest.raises(TimestampError, match=r"duplicate timestamp at sample 5: t\[5\]=0.020000 s after t\[4\]=0.020000 s"):
        validate_trajectory(tr.with_(t=t))
    t = tr.t.copy()
    t[9] = t[8] - 0.1
    with pytest.raises(TimestampError, match=r"time goes backwards at sample 9") as exc:
        validate_trajectory(tr.with_(t=t))
    assert "duplicate" not in str(exc.value)


def test_too_few_samples_is_data_and_excitation_error():
    tr = make_traj(n=3)
    with pytest.raises(TooFewSamplesError) as exc:
        validate_trajectory(tr, min_samples=10)
    assert isinstance(exc.value, DataError) and isinstance(exc.value, ExcitationError)


def test_unknown_joint_and_duplicate_joint_names(ur5):
    names = list(ur5.joint_names)
    tr = make_traj(names=tuple(names[:-1] + ["gripper"]))
    with pytest.raises(JointNameError, match=r"unknown joint\(s\) \['gripper'\].*missing joint\(s\) \['wrist_3_joint'\]"):
        validate_trajectory(tr, ur5)
    with pytest.raises(JointNameError, match="duplicate joint name"):
        validate_trajectory(make_traj(names=("a", "b", "a")))


def test_robot_reorders_joints_without_mutating_input(ur5):
    names = list(ur5.joint_names)
    perm = [3, 0, 5, 1, 4, 2]
    tr = make_traj(names=tuple(names[i] for i in perm))
    tr.extras["current"] = tr.tau * 2.0
    q_before = tr.q.copy()
    out = validate_trajectory(tr, ur5)
    assert out.joint_names == ur5.joint_names
    for j, name in enumerate(names):
        col = tr.joint_names.index(name)
        np.testing.assert_array_equal(out.q[:, j], tr.q[:, col])
        np.testing.assert_array_equal(out.tau[:, j], tr.tau[:, col])
        np.testing.assert_array_equal(out.extras["current"][:, j], tr.extras["current"][:, col])
    assert tr.joint_names[0] == names[3]
    np.testing.assert_array_equal(tr.q, q_before)


def test_degrees_on_limited_joints(panda):
    tr = make_traj(names=panda.joint_names)
    q = tr.q.copy()
    q[:, 1] = np.rad2deg(q[:, 1])  # panda_joint2 limits +-1.76 rad
    q[:, 3] = -1.5  # inside [-3.07, -0.07]
    tr = tr.with_(q=q)
    with pytest.raises(UnitsError, match=r"joint 'panda_joint2' positions reach -?4\d\.\d, beyond its limits \[-1.76, 1.76\] rad: they look like degrees; if the log is in degrees, read it with `angle_unit='deg'`"):
        validate_trajectory(tr, panda)
    assert validate_trajectory(tr, panda, check_units=False).q.shape == tr.q.shape


def test_radians_within_limits_pass_units_check(panda):
    tr = make_traj(names=panda.joint_names)
    q = tr.q.copy()
    q[:, 3] = -1.5
    q[:, 5] = 1.0
    validate_trajectory(tr.with_(q=q), panda)


def test_encoder_counts_and_huge_velocities(ur5):
    tr = make_traj(names=ur5.joint_names)
    q = tr.q.copy()
    q[:, 0] = 5000.0 * np.sin(tr.t)  # not degrees either (5000 deg > limits)
    with pytest.raises(UnitsError, match="'shoulder_pan_joint' positions reach .*degrees or encoder counts"):
        validate_trajectory(tr.with_(q=q), ur5)
    v = tr.v.copy()
    v[:, 2] = 150.0
    with pytest.raises(UnitsError, match="'elbow_joint' velocities reach 150.0 rad/s"):
        validate_trajectory(tr.with_(v=v), ur5)


# ---- readers -----------------------------------------------------------------------
def _frame(tr: Trajectory, t_col="time", fmt=("q_{j}", "v_{j}", "tau_{j}")):
    import pandas as pd

    cols = {t_col: tr.t} if t_col else {}
    for pattern, arr in zip(fmt, (tr.q, tr.v, tr.tau)):
        for k, j in enumerate(tr.joint_names):
            cols[pattern.format(j=j)] = arr[:, k]
    return pd.DataFrame(cols)


def assert_same(a: Trajectory, b: Trajectory, fields=("q", "v", "tau")):
    assert a.joint_names == b.joint_names
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    for f in fields:
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=1e-12, atol=1e-12)


def test_csv_default_header_mapping(tmp_path):
    tr = make_traj(names=("shoulder", "elbow", "wrist"))
    path = tmp_path / "log.csv"
    _frame(tr).to_csv(path, index=False, float_format="%.17g")
    out = read_trajectory(path)
    assert_same(out, tr)
    assert out.a is None and out.source == str(path)


def test_csv_pattern_mapping_infers_joint_names(tmp_path):
    tr = make_traj(names=("a1", "a2", "a3", "a4"))
    path = tmp_path / "log.csv"
    _frame(tr, t_col="stamp", fmt=("pos_{j}", "vel_{j}", "eff_{j}")).to_csv(path, index=False, float_format="%.17g")
    out = read_trajectory(path, columns={"t": "stamp", "q": "pos_{joint}", "v": "vel_{joint}", "tau": "eff_{joint}"})
    assert_same(out, tr)


def test_csv_list_mapping_and_missing_column(tmp_path):
    tr = make_traj(names=("a", "b"))
    path = tmp_path / "log.csv"
    _frame(tr).to_csv(path, index=False, float_format="%.17g")
    out = read_trajectory(path, columns={"q": ["q_a", "q_b"], "tau": ["tau_a", "tau_b"]}, joint_names=["a", "b"])
    assert_same(out, tr, fields=("q", "tau"))  # time found by its default name
    with pytest.raises(DataError) as exc:
        read_trajectory(path, columns={"q": ["q_a", "q_c"]})
    msg = str(exc.value)
    assert str(path) in msg and "'q_c'" in msg and "available columns" in msg and "tau_b" in msg


def test_headerless_index_mapping_needs_rate(tmp_path):
    tr = make_traj(names=("x", "y", "z"))
    path = tmp_path / "log.csv"
    np.savetxt(path, np.hstack([tr.q, tr.v, tr.tau]), delimiter=",", fmt="%.17g")
    out = read_trajectory(path, columns={"q": "0:3", "v": "3:6", "tau": "6:9"}, rate=200, joint_names=NAMES[:3])
    np.testing.assert_allclose(out.t, np.arange(len(tr)) / 200)
    np.testing.assert_array_equal(out.tau, tr.tau)
    assert out.joint_names == NAMES[:3]
    assert read_trajectory(path, columns={"q": "0:3"}, rate=200).joint_names == ("joint_0", "joint_1", "joint_2")
    with pytest.raises(DataError, match=r"no time column in .*log.csv; give the sampling rate: `rate=HZ`"):
        read_trajectory(path, columns={"q": "0:3"})
    with pytest.raises(DataError, match="no header row"):
        read_trajectory(path, rate=200)
    with pytest.raises(DataError, match="'0:12'.*9 columns"):
        read_trajectory(path, columns={"q": "0:12"}, rate=200)


def test_whitespace_txt_headerless(tmp_path):
    tr = make_traj(names=("x", "y"))
    path = tmp_path / "log.txt"
    np.savetxt(path, np.hstack([tr.t[:, None], tr.q]), fmt="%.17g")
    out = read_trajectory(path, columns={"t": 0, "q": "1:3"})
    np.testing.assert_array_equal(out.q, tr.q)
    np.testing.assert_array_equal(out.t, tr.t)


def test_csv_non_numeric_cell_names_column_and_row(tmp_path):
    tr = make_traj(n=20, names=("a", "b"))
    df = _frame(tr).astype(object)
    df.loc[13, "v_b"] = "oops"
    path = tmp_path / "log.csv"
    df.to_csv(path, index=False)
    with pytest.raises(DataError, match=r"log.csv: non-numeric value 'oops' in column 'v_b' \(for 'v'\) at row 13"):
        read_trajectory(path)


def test_csv_empty_cell_is_typed_nonfinite(tmp_path):
    tr = make_traj(n=20, names=("a", "b"))
    df = _frame(tr)
    df.loc[4, "q_a"] = np.nan
    path = tmp_path / "log.csv"
    df.to_csv(path, index=False)
    with pytest.raises(NonFiniteError, match="'q' column 'a' has 1 non-finite values.*sample 4"):
        read_trajectory(path)


def test_time_unit_conversion(tmp_path):
    tr = make_traj(names=("a",))
    df = _frame(tr, t_col="timestamp")
    df["timestamp"] = (tr.t * 1000.0) + 5000.0
    path = tmp_path / "log.csv"
    df.to_csv(path, index=False, float_format="%.17g")
    out = read_trajectory(path, time_unit="ms")
    np.testing.assert_allclose(out.t, tr.t + 5.0, atol=1e-12)
    assert "ms" in out.units["t"]
    with pytest.raises(DataError, match="`time_unit` must be one of"):
        read_trajectory(path, time_unit="min")


def test_missing_file_and_unknown_extension(tmp_path):
    with pytest.raises(DataError, match="nope.npz: no such file"):
        read_trajectory(tmp_path / "nope.npz")
    bad = tmp_path / "log.xlsx"
    bad.write_text("x")
    with pytest.raises(DataError, match=r"unsupported file type '.xlsx'; supported: \.csv, \.txt, \.dat, \.log, \.npz.*\.feather"):
        read_trajectory(bad)
    junk = tmp_path / "junk.npz"
    junk.write_text("not a zip")
    with pytest.raises(DataError, match="junk.npz: not a readable NPZ"):
        read_trajectory(junk)
    text = tmp_path / "text.npz"
    np.savez(text, positions=np.array(["a", "b"]))
    with pytest.raises(DataError, match=r"^\S*text.npz: array 'positions' is not numeric"):
        read_trajectory(text)


def test_npz_round_trip_and_robot_reorder(tmp_path, ur5):
    names = list(ur5.joint_names)
    tr = make_traj(names=tuple(names[::-1]))
    tr.extras["current"] = tr.tau * 0.1
    path = write_npz(tr, tmp_path / "log.npz")
    assert path == tmp_path / "log.npz"
    back = read_trajectory(path)
    assert_same(back, tr, fields=("q", "v", "a", "tau"))
    np.testing.assert_array_equal(back.extras["current"], tr.extras["current"])
    ordered = read_trajectory(path, robot=ur5)
    assert ordered.joint_names == ur5.joint_names
    np.testing.assert_array_equal(ordered.q, tr.q[:, ::-1])


def test_npz_custom_keys_and_missing_positions(tmp_path):
    tr = make_traj(names=("a", "b"))
    path = tmp_path / "custom.npz"
    np.savez(path, stamp=tr.t, joint_pos=tr.q, qd=tr.v)
    out = read_trajectory(path, columns={"t": "stamp", "q": "joint_pos"})
    np.testing.assert_array_equal(out.v, tr.v)  # 'qd' is a default alias
    assert out.joint_names == ("joint_0", "joint_1")
    with pytest.raises(DataError, match=r"no joint positions found.*'joint_pos'"):
        read_trajectory(path)
    with pytest.raises(DataError, match="no array 'pos'"):
        read_trajectory(path, columns={"q": "pos"})


def test_parquet_round_trip(tmp_path):
    tr = make_traj(names=("a", "b", "c"))
    path = tmp_path / "log.parquet"
    _frame(tr, t_col="t").to_parquet(path)
    assert_same(read_trajectory(path), tr)
    out = read_trajectory(path, columns={"q": "q_{joint}", "tau": ["tau_a", "tau_b", "tau_c"]})
    assert_same(out, tr, fields=("q", "tau"))


def test_hdf5_top_level_and_nested(tmp_path):
    import h5py

    tr = make_traj(names=("a", "b", "c"))
    path = tmp_path / "log.h5"
    with h5py.File(path, "w") as f:
        f["time"] = tr.t
        f["position"] = tr.q
        f["velocity"] = tr.v
        f["effort"] = tr.tau
        f["joint_names"] = np.array(tr.joint_names, dtype="S")
    assert_same(read_trajectory(path), tr)
    nested = tmp_path / "nested.hdf5"
    with h5py.File(nested, "w") as f:
        g = f.create_group("robot/state")
        g["stamp"] = tr.t
        g["torques"] = tr.tau
        g["positions"] = tr.q
        f.attrs["joint_names"] = list(tr.joint_names)
    out = read_trajectory(nested, columns={"t": "/robot/state/stamp"})
    assert_same(out, tr, fields=("q", "tau"))


# ---- filtering ------------------------------------------------------------------------
def _sine_traj(rate=200.0, f=1.0, duration=4.0):
    t = np.arange(0, duration, 1 / rate)
    w = 2 * np.pi * f
    q = np.column_stack([np.sin(w * t), 0.5 * np.cos(w * t)])
    return Trajectory(t=t, q=q, joint_names=("a", "b")), w


def test_savgol_derivatives_of_sine_match_analytic():
    tr, w = _sine_traj()
    out = savgol_derivatives(tr, polyorder=3, window=21)  # 0.1 s at 200 Hz
    assert "savgol" in out.units["processing"]
    from sensorless.data import default_savgol_window

    assert f"window={default_savgol_window(200.0)}," in savgol_derivatives(tr).units["processing"]  # 0.2 s = 41
    inner = slice(21, -21)
    v_true = w * np.column_stack([np.cos(w * tr.t), -0.5 * np.sin(w * tr.t)])
    a_true = -(w**2) * tr.q
    v_err = np.abs(out.v - v_true)[inner].max() / np.abs(v_true).max()
    a_err = np.abs(out.a - a_true)[inner].max() / np.abs(a_true).max()
    assert v_err < 1e-3 and a_err < 1e-2, (v_err, a_err)
    assert np.abs(out.q - tr.q)[inner].max() < 1e-3
    np.testing.assert_array_equal(out.t, tr.t)


def test_causal_savgol_exact_on_polynomials_and_causal():
    dt = 0.005
    t = np.arange(300) * dt
    c = (0.3, 0.5, -0.8, 0.4)
    q = c[0] + c[1] * t + c[2] * t**2 + c[3] * t**3
    v = c[1] + 2 * c[2] * t + 3 * c[3] * t**2
    a = 2 * c[2] + 6 * c[3] * t
    sg = SavitzkyGolay(window=15, polyorder=3, dt=dt, causal=True)
    assert sg.delay == 0.0 and sg.warmup == 14
    np.testing.assert_allclose(sg.apply(q), q, atol=1e-9)
    np.testing.assert_allclose(sg.apply(q, 1), v, atol=1e-9)
    np.testing.assert_allclose(sg.apply(q, 2), a, atol=1e-9)
    # causality: changing sample k leaves every output before k (after warm-up) unchanged
    noisy = np.random.default_rng(1).normal(size=300)
    changed = noisy.copy()
    changed[200:] += 10.0
    d0, d1 = sg.apply(noisy, 1), sg.apply(changed, 1)
    np.testing.assert_array_equal(d0[:200], d1[:200])
    assert np.all(d0[200:215] != d1[200:215])
    # the centred filter has a lower noise gain than the causal one
    assert SavitzkyGolay(15, 3, dt).noise_gain(1) < sg.noise_gain(1)


def test_savgol_rejects_bad_parameters():
    with pytest.raises(DataError, match="odd"):
        SavitzkyGolay(window=10, polyorder=3, dt=0.01)
    with pytest.raises(DataError, match="polyorder"):
        SavitzkyGolay(window=5, polyorder=5, dt=0.01)
    with pytest.raises(TooFewSamplesError):
        SavitzkyGolay(window=21, polyorder=3, dt=0.01).apply(np.zeros(10))


def _amplitude(x, t, f):
    """Amplitude of the f-Hz component of x (least squares on sin/cos)."""
    A = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
    coef, *_ = np.linalg.lstsq(A, x, rcond=None)
    return float(np.hypot(*coef))


def test_lowpass_attenuates_50hz_and_preserves_1hz():
    rate = 1000.0
    t = np.arange(0, 4, 1 / rate)
    slow = np.sin(2 * np.pi * t)
    noise = 0.3 * np.sin(2 * np.pi * 50 * t + 0.3)
    tr = Trajectory(t=t, q=(slow + noise)[:, None], joint_names=("a",), tau=(2 * slow + noise)[:, None])
    out = lowpass(tr, cutoff_hz=10.0)
    inner = slice(500, -500)
    y, ti = out.q[inner, 0], t[inner]
    atten_db = 20 * np.log10(_amplitude(y, ti, 50) / 0.3)
    assert atten_db < -20, atten_db
    assert abs(_amplitude(y, ti, 1) - 1.0) < 0.01
    assert abs(_amplitude(out.tau[inner, 0], ti, 1) - 2.0) < 0.02
    assert "lowpass" in out.units["processing"]
    np.testing.assert_array_equal(tr.q[:, 0], slow + noise)  # input untouched


def test_lowpass_requires_uniform_sampling_and_valid_cutoff():
    tr = make_traj()
    t = tr.t.copy()
    t[100:] += 0.003  # one 8 ms gap in a 5 ms log
    with pytest.raises(DataError, match="uniform sampling.*resample_uniform"):
        lowpass(tr.with_(t=t), 10.0)
    with pytest.raises(DataError, match="Nyquist"):
        butter_lowpass(tr.q, 150.0, 200.0)
    with pytest.raises(TooFewSamplesError):
        butter_lowpass(np.zeros(10), 5.0, 200.0)


def test_trim_bounds_and_relative():
    tr = make_traj(n=200)  # t = 0 .. 0.995
    out = trim(tr, 0.1, 0.5)
    assert out.t[0] == pytest.approx(0.1) and out.t[-1] == pytest.approx(0.5)
    assert len(out) == 81 and out.q.shape == (81, 7)
    np.testing.assert_array_equal(out.tau, tr.tau[20:101])
    shifted = tr.with_(t=tr.t + 1000.0)
    assert len(trim(shifted, 0.1, 0.5, relative=True)) == 81
    assert len(trim(tr, t_start=0.9)) == 20
    with pytest.raises(DataError, match="no sample"):
        trim(tr, 5.0, 6.0)


def test_decimate_shapes_values_and_antialias():
    rate = 1000.0
    t = np.arange(0, 2, 1 / rate)
    slow = np.sin(2 * np.pi * 2 * t)
    alias = 0.5 * np.sin(2 * np.pi * 180 * t)  # above the new Nyquist (100 Hz): would alias to 20 Hz
    tr = Trajectory(t=t, q=(slow + alias)[:, None], joint_names=("a",), v=np.ones((t.size, 1)))
    out = decimate(tr, 5)
    assert len(out) == 400 and out.q.shape == (400, 1)
    np.testing.assert_array_equal(out.t, t[::5])
    inner = slice(50, -50)
    np.testing.assert_allclose(out.q[inner, 0], slow[::5][inner], atol=5e-3)
    np.testing.assert_allclose(out.v, 1.0, atol=1e-9)
    raw = decimate(tr, 5, antialias=False)
    np.testing.assert_array_equal(raw.q, tr.q[::5])
    assert len(decimate(tr, 1)) == len(tr)
    with pytest.raises(DataError, match="factor"):
        decimate(tr, 0)


def test_resample_uniform_linear_exact():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.003, 0.007, 500))
    q = np.column_stack([2.0 * t + 1.0, -t])
    tr = Trajectory(t=t, q=q, joint_names=("a", "b"), tau=3.0 * q, extras={"current": q.copy()})
    out = resample_uniform(tr, rate_hz=200.0)
    dt = np.diff(out.t)
    np.testing.assert_allclose(dt, 0.005, rtol=1e-9)
    assert out.t[0] == t[0] and out.t[-1] <= t[-1] + 1e-9
    assert len(out) == int(np.floor((t[-1] - t[0]) * 200 + 1e-9)) + 1
    np.testing.assert_allclose(out.q[:, 0], 2.0 * out.t + 1.0, atol=1e-9)
    np.testing.assert_allclose(out.tau, 3.0 * out.q, atol=1e-9)
    np.testing.assert_allclose(out.extras["current"], out.q, atol=1e-9)
    lowpass(out, 20.0)  # now uniform
    default = resample_uniform(tr)
    assert default.rate == pytest.approx(tr.rate, rel=1e-9)


# ---- real data -----------------------------------------------------------------------
@pytest.mark.realdata
def test_read_kuka_npz():
    if not (KUKA_NPZ.is_file() and KUKA_URDF.is_file()):
        pytest.skip(f"real data not available: {KUKA_NPZ}")
    from sensorless.robot import load_robot

    robot = load_robot(KUKA_URDF)
    tr = read_trajectory(KUKA_NPZ, robot=robot)
    assert len(tr) == 5027 and tr.n_joints == 7
    assert tr.joint_names == tuple(f"lwr_{i}_joint" for i in range(7))
    assert tr.rate == pytest.approx(200.0, rel=0.01)
    assert tr.v.shape == tr.a.shape == tr.tau.shape == (5027, 7)
    with pytest.raises(DataError, match="resample_uniform"):
        lowpass(tr, 10.0)  # the log has 3.4..6.5 ms jitter
    smooth = savgol_derivatives(resample_uniform(tr))
    # the stored velocities agree with the Savitzky-Golay derivative of the positions
    rms = np.sqrt(np.mean((smooth.v[20:-20] - resample_uniform(tr).v[20:-20]) ** 2, axis=0))
    assert np.all(rms < 0.05 * np.abs(tr.v).max(axis=0))


@pytest.mark.realdata
def test_read_dvrk_headerless_csv():
    if not DVRK_CSV.is_file():
        pytest.skip(f"real data not available: {DVRK_CSV}")
    tr = read_trajectory(DVRK_CSV, columns={"q": "0:7", "v": "7:14", "tau": "14:21"}, rate=200)
    assert len(tr) == 5999 and tr.n_joints == 7
    assert tr.q.shape == tr.v.shape == tr.tau.shape == (5999, 7)
    assert tr.duration == pytest.approx(5998 / 200)
    assert tr.a is None
    assert tr.q[0, 0] == pytest.approx(-0.43909142302978293, abs=0)
