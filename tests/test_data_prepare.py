"""Logs of motor currents: drive gains (τ = K·i), trim windows, resampling of jittery
stamps, gap detection, and keeping the logged velocity (issues 11 and 17)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.run.logs import load_logs
from sensorless.data import Trajectory, TrimWindow, prepare, read_trajectory, resample, timing, trim_window
from sensorless.errors import DataError, DataWarning, JointNameError, ShapeMismatchError, TimestampError
from sensorless.excitation import random_fourier
from sensorless.testing import perturbed_truth, synthetic_trajectory

runner = CliRunner()
GAINS = np.array([10.0, 10.7, 9.6, 4.3, 4.1, 4.0])


def _current_csv(path, traj, gains=GAINS, t=None):
    """CSV with time, pos_<j>, vel_<j>, i_<j> = tau / K (joint order of ``traj``)."""
    table = {"time": traj.t if t is None else t}
    table.update({f"pos_{j}": traj.q[:, k] for k, j in enumerate(traj.joint_names)})
    table.update({f"vel_{j}": traj.v[:, k] for k, j in enumerate(traj.joint_names)})
    table.update({f"i_{j}": traj.tau[:, k] / gains[k] for k, j in enumerate(traj.joint_names)})
    pd.DataFrame(table).to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def ur5_log(ur5):
    truth = perturbed_truth(ur5, rng=0)
    return synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(100, 10.0), noise_std=0.05, rng=2)


# ---- gains -----------------------------------------------------------------------
def test_gains_on_column_map_give_tau_equal_K_times_current(tmp_path, ur5_log, ur5):
    f = _current_csv(tmp_path / "cur.csv", ur5_log)
    raw = pd.read_csv(f)
    i = raw[[f"i_{j}" for j in ur5.joint_names]].to_numpy()
    spec = "i_*:gain=" + ",".join(map(str, GAINS))
    tr = read_trajectory(f, columns={"q": "pos_{joint}", "v": "vel_{joint}", "tau": spec}, robot=ur5)
    np.testing.assert_array_equal(tr.tau, i * GAINS)
    np.testing.assert_array_equal(tr.extras["current"], i)
    assert tr.provenance["gains"] == dict(zip(ur5.joint_names, GAINS))
    assert "current" in tr.provenance["tau"]


def test_gains_file_by_name_follows_joints_not_column_order(tmp_path, ur5_log, ur5):
    shuffled = ur5_log.select_joints(list(reversed(ur5.joint_names)))
    f = _current_csv(tmp_path / "rev.csv", shuffled, gains=GAINS[::-1])
    gfile = tmp_path / "gains.json"
    gfile.write_text(json.dumps(dict(zip(ur5.joint_names, GAINS.tolist()))))
    cols = {"q": "pos_{joint}", "v": "vel_{joint}", "tau": "i_{joint}"}
    tr = read_trajectory(f, columns=cols, gains=gfile, robot=ur5)  # reordered to the robot's joints
    np.testing.assert_allclose(tr.tau, ur5_log.tau, rtol=1e-12, atol=1e-12)
    csvg = tmp_path / "gains.csv"
    csvg.write_text("joint,gain\n" + "\n".join(f"{j},{g}" for j, g in zip(ur5.joint_names, GAINS)))
    np.testing.assert_array_equal(read_trajectory(f, columns=cols, gains=str(csvg), robot=ur5).tau, tr.tau)


def test_gains_from_current_field_and_errors(tmp_path, ur5_log, ur5):
    f = _current_csv(tmp_path / "cur.csv", ur5_log)
    cols = {"q": "pos_{joint}", "current": "i_{joint}"}
    tr = read_trajectory(f, columns=cols, gains=list(GAINS), robot=ur5)
    np.testing.assert_allclose(tr.tau, ur5_log.tau, rtol=1e-12, atol=1e-12)
    with pytest.raises(ShapeMismatchError, match="5 gains for 6 joints"):
        read_trajectory(f, columns=cols, gains=list(GAINS[:5]))
    with pytest.raises(JointNameError, match="no gain for joint.*wrist_3_joint"):
        read_trajectory(f, columns=cols, gains=dict(zip(ur5.joint_names[:5], GAINS)))
    with pytest.raises(DataError, match="non-zero"):
        read_trajectory(f, columns=cols, gains="1,2,3,0,5,6")
    with pytest.raises(DataError, match="both torque and current"):
        read_trajectory(f, columns={**cols, "tau": "i_{joint}"}, gains=2.0)
    with pytest.raises(DataError, match="given twice"):
        read_trajectory(f, columns={"q": "pos_{joint}", "tau": "i_{joint}:gain=1,2,3,4,5,6"}, gains=2.0)
    with pytest.raises(DataError, match="only to 'tau' or 'current'"):
        read_trajectory(f, columns={"q": "pos_{joint}:gain=2"})
    with pytest.raises(DataError, match="no current columns"):
        read_trajectory(f, columns={"q": "pos_{joint}"}, gains=2.0)


# ---- trim ------------------------------------------------------------------------
def _ramp_traj(n=1001, rate=100.0, t0=1000.0):
    t = t0 + np.arange(n) / rate
    q = np.sin(np.arange(n) / rate)[:, None]
    return Trajectory(t=t, q=q, joint_names=("j",), source="<ramp>")


@pytest.mark.parametrize("spec, first, last", [
    ("1:3", 1.0, 3.0), (":3", 0.0, 3.0), ("1:", 1.0, 10.0), ("2:-3", 2.0, 7.0), ("-1:", 9.0, 10.0),
    ("abs:1004.5:1005", 4.5, 5.0), ((1.0, 3.0), 1.0, 3.0),
])
def test_trim_boundaries_are_inclusive_and_relative_to_first_sample(spec, first, last):
    tr = _ramp_traj()
    out = trim_window(tr, spec)
    assert out.t[0] - tr.t[0] == pytest.approx(first) and out.t[-1] - tr.t[0] == pytest.approx(last)
    rel = tr.t - tr.t[0]
    assert len(out) == int(np.sum((rel >= first - 1e-9) & (rel <= last + 1e-9)))
    assert out.provenance["trim"]["samples"] == len(out)


@pytest.mark.parametrize("spec, err, needle", [
    ("5:4", DataError, "empty"), ("20:30", DataError, "outside the log"), (":-20", DataError, "outside the log"),
    ("1.001:1.009", DataError, "holds 0 sample"), ("a:b", DataError, "not a number"), ("1-3", DataError, "START:END"),
])
def test_trim_errors_name_the_window_and_the_log_span(spec, err, needle):
    with pytest.raises(err, match=needle) as exc:
        trim_window(_ramp_traj(), spec)
    assert "<ramp>" in str(exc.value)
    if needle != "not a number" and needle != "START:END":
        assert "the log spans" in str(exc.value)


def test_trim_window_parse_round_trip():
    for s in ("1.9:49.6", ":49.6", "1.9:", "abs:10:20", "2:-3"):
        assert str(TrimWindow.parse(s)) == s


# ---- resampling ------------------------------------------------------------------
def _jittered(rate=100.0, duration=20.0, jitter=0.2, seed=0, duplicates=()):
    rng = np.random.default_rng(seed)
    n = int(duration * rate)
    t_true = np.maximum.accumulate(np.arange(n) / rate + rng.normal(0, jitter / rate, n))
    w = 2 * np.pi * np.array([0.3, 0.7])
    q = np.sin(np.outer(t_true, w))
    v = w * np.cos(np.outer(t_true, w))
    stamp = t_true.copy()
    for k in duplicates:
        stamp[k] = stamp[k - 1]
    tau = 3.0 * q
    return Trajectory(t=stamp, q=q, v=v, tau=tau, joint_names=("a", "b"), source="<jitter>"), w


def test_resampling_jittered_stamps_recovers_the_signal():
    tr, w = _jittered()
    info = timing(tr.t)
    assert info.jitter > 0.1 and not info.is_uniform()
    out = prepare(tr, resample="auto", savgol_window=None)
    dt = np.diff(out.t)
    np.testing.assert_allclose(dt, dt[0], rtol=1e-6)  # uniform grid
    assert timing(out.t).is_uniform()
    assert abs(1 / dt[0] - 100.0) < 1.0
    q_true = np.sin(np.outer(out.t, w))
    v_true = w * np.cos(np.outer(out.t, w))
    assert np.max(np.abs(out.q - q_true)) < 1e-5  # cubic interpolation of a 0.7 Hz sine at 100 Hz
    assert np.max(np.abs(out.v - v_true)) < 1e-4
    assert np.max(np.abs(out.tau - 3.0 * q_true)) < 5e-3  # linear: error ≤ h²/8 max|τ''|
    a_true = -(w**2) * np.sin(np.outer(out.t, w))
    assert np.max(np.abs(out.a - a_true)[20:-20]) < 1e-2  # v̇ = d/dt of the (resampled) logged v
    assert out.provenance["resampled"]["before"]["jitter"] == pytest.approx(info.jitter)


def test_uniform_log_is_not_resampled_in_auto_mode():
    tr, _ = _jittered(jitter=0.0)
    out = prepare(tr, resample="auto")
    np.testing.assert_array_equal(out.t, tr.t)
    np.testing.assert_array_equal(out.v, tr.v)
    assert "resampled" not in out.provenance


def test_duplicate_stamps_are_merged_by_the_resampler_and_refused_when_off():
    tr, w = _jittered(duplicates=(100, 500, 501))
    out = resample(tr)
    assert out.provenance["resampled"]["duplicates_merged"] == 3
    assert np.all(np.diff(out.t) > 0)
    assert np.max(np.abs(out.q - np.sin(np.outer(out.t, w)))) < 0.05
    with pytest.raises(TimestampError, match=r"duplicate timestamp at sample 100 .*`resample='auto'`"):
        prepare(tr, resample="off")


def test_gap_is_an_error_naming_the_samples():
    tr, _ = _jittered(jitter=0.05)
    t = tr.t.copy()
    t[700:] += 0.5  # the logger stalled for half a second before sample 700
    with pytest.raises(TimestampError, match=r"gap of 5\d\d\.\d ms between sample 699 \(t=6\.9\d+ s\) and sample 700"):
        prepare(tr.with_(t=t), resample="auto")
    out = prepare(tr.with_(t=t), resample="auto", max_gap=60)  # tolerance raised: interpolated through
    assert timing(out.t).is_uniform()


def test_backwards_time_is_still_an_error(tmp_path):
    tr, _ = _jittered(jitter=0.0)
    t = tr.t.copy()
    t[300] = t[298]
    with pytest.raises(TimestampError, match="time goes backwards at sample 300"):
        resample(tr.with_(t=t))


def test_jitter_without_resampling_says_to_resample():
    tr, _ = _jittered()
    with pytest.raises(DataError, match="resampling is off.*`resample='auto'`"):
        prepare(tr.with_(v=None), resample="off")


# ---- keep the logged velocity ----------------------------------------------------
def test_logged_velocity_is_kept_and_differentiated_once(ur5_log):
    """v logged as 1.3 × dq/dt: kept bit for bit (with a warning naming the scale), and v̇ follows it
    (1.3 × q̈), not q."""
    tr = ur5_log.with_(v=1.3 * ur5_log.v, a=None)
    with pytest.warns(DataWarning, match=r"v = 1\.3·dq/dt"):
        out = prepare(tr)
    np.testing.assert_array_equal(out.v, tr.v)
    inner = slice(10, -10)
    np.testing.assert_allclose(out.a[inner], 1.3 * ur5_log.a[inner], atol=0.05 * np.abs(ur5_log.a).max())
    assert out.provenance["v"] == "logged" and out.provenance["a"].startswith("derived: d/dt of logged v")
    forced = prepare(tr, velocity="from-q")
    np.testing.assert_allclose(forced.v[inner], ur5_log.v[inner], atol=0.02 * np.abs(ur5_log.v).max())
    assert forced.provenance["v"].startswith("derived: d/dt q")
    no_v = prepare(tr.with_(v=None))
    assert no_v.provenance["v"].startswith("derived: d/dt q")


def test_cli_load_logs_keeps_the_logged_velocity(tmp_path, ur5_log, ur5):
    f = _current_csv(tmp_path / "cur.csv", ur5_log.with_(v=1.3 * ur5_log.v))
    (tr,) = load_logs([f], ur5, "q=pos_{joint};v=vel_{joint};tau=i_{joint}", None, None, None, 1,
                      gains=",".join(map(str, GAINS)))
    np.testing.assert_allclose(tr.v, 1.3 * ur5_log.v, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(tr.tau, ur5_log.tau, rtol=1e-12, atol=1e-12)


# ---- CLI: identify records it, predict and estimate-force replay it -------------------
def test_predict_and_estimate_force_apply_the_models_preprocessing(tmp_path, ur5):
    truth = perturbed_truth(ur5, rng=0)
    logs = []
    for k, seed in enumerate((1, 3)):
        tr = synthetic_trajectory(truth, random_fourier(ur5, rng=seed).sample(100, 10.0), noise_std=0.05, rng=seed + 1)
        t = tr.t + np.random.default_rng(seed).normal(0, 0.002, len(tr))  # jittered stamps (values unchanged)
        logs.append(_current_csv(tmp_path / f"log{k}.csv", tr, t=np.maximum.accumulate(t)))
    model = tmp_path / "model"
    cols = "q=pos_{joint};v=vel_{joint};tau=i_*:gain=" + ",".join(map(str, GAINS))
    r = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(logs[0]), "--columns", cols,
                            "--trim", "0.5:-0.5", "--savgol-window", "15", "--out", str(model)])
    assert r.exit_code == 0, r.output
    doc = json.loads((model / "result.json").read_text())
    prep = doc["settings"]["preprocessing"]
    assert prep["gains"] == dict(zip(ur5.joint_names, GAINS)) and prep["savgol_window"] == 15
    assert prep["columns"]["tau"] == "i_{joint}" and prep["trim"] == "0.5:-0.5"
    sig = doc["settings"]["signals"][str(logs[0])]
    assert sig["v"] == "logged" and "window 15" in sig["a"] and "resampled" in sig and "current" in sig["tau"]

    out = tmp_path / "pred.npz"
    r = runner.invoke(app, ["predict", "--robot", "ur5", "--model", str(model), "--data", str(logs[1]), "--out", str(out)])
    assert r.exit_code == 0, r.output  # no --columns/--gains: the model's are used
    z = np.load(out)
    used = json.loads(str(z["preprocessing"]))
    assert used["savgol_window"] == 15 and used["signals"]["a"].startswith("derived: d/dt of logged v")
    rel = np.sqrt(np.mean((z["tau_pred"] - z["tau_measured"]) ** 2, 0)) / np.ptp(z["tau_measured"], 0)
    assert np.all(rel < 0.05), rel  # currents scaled by the model's gains match the predicted torques
    off = tmp_path / "off.npz"
    r = runner.invoke(app, ["predict", "--robot", "ur5", "--model", str(model), "--data", str(logs[1]),
                            "--gains", "off", "--out", str(off)])
    assert r.exit_code == 0, r.output
    np.testing.assert_allclose(z["tau_measured"], np.load(off)["tau_measured"] * GAINS, rtol=1e-9, atol=1e-9)

    force = tmp_path / "force.npz"
    r = runner.invoke(app, ["estimate-force", "--robot", "ur5", "--model", str(model), "--data", str(logs[1]),
                            "--frame", "tool0", "--trim", "1:-1", "--out", str(force)])
    assert r.exit_code == 0, r.output
    assert len(np.load(force)["t"]) < len(z["t"])  # trimmed, and read with the model's column map and gains


def test_cli_bad_trim_and_gap_are_one_line_errors_without_output(tmp_path, ur5_log):
    f = _current_csv(tmp_path / "cur.csv", ur5_log)
    cols = "q=pos_{joint};v=vel_{joint};tau=i_{joint}"
    out = tmp_path / "o"
    r = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(f), "--columns", cols, "--gains", "2",
                            "--trim", "30:40", "--out", str(out)])
    assert r.exit_code == 2 and "outside the log" in r.output and "cur.csv" in r.output and not out.exists()
    t = ur5_log.t.copy()
    t[400:] += 1.0
    g = _current_csv(tmp_path / "gap.csv", ur5_log, t=t)
    r = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(g), "--columns", cols, "--gains", "2",
                            "--resample", "100", "--out", str(out)])
    assert r.exit_code == 2 and "gap of" in r.output and "sample 400" in r.output and not out.exists()


def test_derived_accelerations_that_are_mostly_quantization_noise_are_named():
    """Issue 40: v and v̇ differentiated from a position in 0.25 mm quanta over a short window carry more noise
    than motion; the noise each joint's v̇ gets (σ of q floored at its quantum, through the window) is recorded
    and a warning names the joint, with the window that would bring it to a quarter of the motion."""
    from sensorless.data import prepare

    t = np.arange(4000) / 1000.0
    slow = 0.002 * np.sin(2 * np.pi * 0.5 * t)  # 2 mm at 0.5 Hz: v̇ RMS 14 mm/s²
    fine = 0.5 * np.sin(2 * np.pi * 1.0 * t)
    q = np.column_stack([np.round(slow / 2.5e-4) * 2.5e-4, fine])
    traj = Trajectory(t=t, q=q, tau=np.zeros_like(q), joint_names=("slider", "hip"))
    with pytest.warns(DataWarning, match=r"derived accelerations of slider \(σ .* a window of \d+ samples would"):
        out = prepare(traj, savgol_window=23)
    info = out.provenance["derivative_noise"]
    assert info["window_samples"] == 23 and info["from"] == "q"
    assert info["noise_std"]["slider"] > 0.5 * info["rms"]["slider"]
    assert info["noise_std"]["hip"] < 0.01 * info["rms"]["hip"]
    assert out.provenance["resolution"]["q"]["slider"]["step"] == pytest.approx(2.5e-4)
