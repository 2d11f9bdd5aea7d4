"""Issue 17: per-joint terms, Stribeck / noise-aware Coulomb friction, drive gains, --data a b c,
link names. Reduced versions of the real-arm acceptance (sensorless_studies.benchmarks.real_arm)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.cli.common import expand_multi_values
from sensorless.data.prepare import load_log
from sensorless.identification.drive_gains import identify_drive_gains
from sensorless.identification.friction import (
    coulomb_smoothing_from_noise,
    lowpass_noise_gain,
    search_stribeck_velocity,
)
from sensorless.data.rest import signal_noise
from sensorless.regressor import ModelStructure
from sensorless.regressor.joint_spec import parse_joint_terms
from sensorless_studies.simulation.current_arm import drive_gains_for, simulate, truth_model, with_payload

COLS = "q=pos_{joint};v=vel_{joint};tau=i_{joint}"


@pytest.fixture(scope="module")
def ur10_logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("ur10")
    robot, truth = truth_model("ur10", 0, stribeck=True, friction_scale=4.0)
    K = drive_gains_for(robot)
    kw = dict(motion=10.0, idle_start=1.5, idle_end=1.0, ramp=1.0)
    simulate(robot, truth, K, seed=1, **kw).to_csv(d / "a.csv", index=False)
    simulate(robot, truth, K, seed=2, **kw).to_csv(d / "b.csv", index=False)
    simulate(robot, truth, K, seed=3, motion_seed=30, **kw).to_csv(d / "u.csv", index=False)
    simulate(robot, with_payload(truth, "tool0", 4.0), K, seed=4, motion_seed=30, **kw).to_csv(d / "l.csv", index=False)
    (d / "gains.json").write_text(json.dumps(dict(zip(robot.actuated_joints, map(float, K)))))
    return d, robot, truth, K


def test_data_takes_several_values_after_one_flag():
    multi = {"--data", "--validate"}
    assert expand_multi_values(["--data", "a", "b", "--out", "o", "--validate", "c", "d"], multi) == [
        "--data", "a", "--data", "b", "--out", "o", "--validate", "c", "--validate", "d"]
    assert expand_multi_values(["--data=a", "b", "--force"], multi) == ["--data=a", "--data", "b", "--force"]
    assert expand_multi_values(["--data", "a", "--data", "b"], multi) == ["--data", "a", "--data", "b"]


def test_per_joint_terms_parse_and_name_the_bad_joint_or_term():
    joints = ("j1", "j2", "j3")
    assert parse_joint_terms("j1=fv,fc,offset;j3=fv", joints) == {"j1": ("fv", "fc", "offset"), "j2": (), "j3": ("fv",)}
    assert parse_joint_terms("j1=fv;*=fc", joints)["j2"] == ("fc",)
    from sensorless.errors import RobotModelError

    with pytest.raises(RobotModelError, match="nope"):
        parse_joint_terms("nope=fv", joints)
    with pytest.raises(RobotModelError, match="visc"):
        parse_joint_terms("j1=visc", joints)


@pytest.mark.parametrize("spec,needle", [("elbo=fv", "elbo"), ("elbow_joint=fv,stiction", "stiction")])
def test_cli_joint_terms_error_names_it_and_writes_nothing(ur10_logs, tmp_path, spec, needle):
    d, *_ = ur10_logs
    r = CliRunner().invoke(app, ["identify", "--robot", "ur10", "--data", str(d / "a.csv"), "--columns", COLS,
                                 "--gains", str(d / "gains.json"), "--joint-terms", spec, "--out", str(tmp_path / "m")])
    assert r.exit_code == 2 and needle in r.output and "--joint-terms" in r.output
    assert not (tmp_path / "m").exists()


def test_stribeck_velocity_search_recovers_vs():
    rng = np.random.default_rng(0)
    v = rng.uniform(-0.6, 0.6, 4000)
    fc, fs, vs, fv = 2.0, 3.5, 0.05, 0.4
    r = fc * np.sign(v) + (fs - fc) * np.exp(-((v / vs) ** 2)) * np.sign(v) + fv * v + rng.normal(0, 0.05, v.size)
    grid = np.geomspace(0.005, 0.3, 40)
    best, sse = search_stribeck_velocity(v, r, eps=0.0, terms=("fv", "fc", "stribeck"), grid=grid)
    assert abs(best / vs - 1) < 0.15 and sse.min() < 0.5 * sse.max()


def test_noise_estimate_and_smoothing_rule_bound_the_chatter_at_rest():
    rng = np.random.default_rng(1)
    t = np.arange(5000) / 100.0
    sig_v, sig_tau, fs = 1e-3, 0.05, 4.0
    v = np.column_stack([np.sin(0.7 * t), np.cos(0.3 * t)]) + rng.normal(0, sig_v, (t.size, 2))
    est = signal_noise(v)
    assert np.allclose(est, sig_v, rtol=0.1)
    eps = coulomb_smoothing_from_noise(est, sigma_tau=np.full(2, sig_tau), static_friction=np.full(2, fs))
    at_rest = fs * np.tanh(rng.normal(0, sig_v, (20000, 2)) / eps)  # model torque of a robot at rest
    assert np.all(at_rest.std(axis=0) <= 0.6 * sig_tau)  # predicted σ_τ/2: residual √(σ² + chatter²) < 2σ
    g = lowpass_noise_gain(5.0, 100.0)  # white noise through the zero-phase 5 Hz Butterworth
    from sensorless.data.filtering import butter_lowpass

    assert abs(butter_lowpass(rng.normal(0, 1, 200000), 5.0, 100.0).std() / g - 1) < 0.05


def test_identify_cli_per_joint_terms_auto_friction_saved_and_reloaded(ur10_logs, tmp_path):
    d, robot, truth, K = ur10_logs
    out = tmp_path / "m"
    spec = "wrist_3_joint=fv,offset;*=fv,fc,stribeck,offset,armature"
    r = CliRunner().invoke(app, ["identify", "--robot", "ur10", "--data", str(d / "a.csv"), str(d / "b.csv"),
                                 "--columns", COLS, "--gains", str(d / "gains.json"), "--trim", "1.5:-1",
                                 "--savgol-window", "21", "--lowpass", "5", "--joint-terms", spec, "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "result.json").read_text())
    assert len(doc["settings"]["data"]) == 2  # --data a b
    assert set(doc["joint_terms"]["wrist_3_joint"]) == {"fv", "offset"}
    assert "stribeck" in doc["joint_terms"]["elbow_joint"]
    fr = doc["settings"]["friction"]
    assert fr["coulomb_smoothing_mode"] == "auto" and all(e > 0 for e in fr["coulomb_smoothing"].values())
    assert doc["parameter_links"]["shoulder_pan_joint.m"] == "shoulder_link.m"
    jt = json.loads((out / "joint_terms.json").read_text())  # the whole friction law, Stribeck included
    kept = [j for j, t in doc["joint_terms"].items() if "stribeck" in t]
    assert kept and "stribeck" not in jt["wrist_3_joint"]
    width = {j: fr["transition_width"][j] or fr["coulomb_smoothing"][j] for j in fr["transition_width"]}
    assert set(width) == set(robot.actuated_joints) - {"wrist_3_joint"}  # searched on every joint with fc
    for j in kept:
        assert jt[j]["stribeck"] == pytest.approx(doc["joint_terms"][j]["stribeck"])
        assert jt[j]["stribeck_velocity"] == pytest.approx(fr["stribeck_velocity"][j])
        assert jt[j]["coulomb_smoothing"] == pytest.approx(width[j])  # the width the law uses
    assert (out / "friction.png").stat().st_size > 10_000
    from sensorless.torque_models import load_parameters

    st, p = load_parameters(out / "result.json", robot)
    assert st.terms_of("wrist_3_joint") == ("fv", "offset")
    assert st.smoothing_of("elbow_joint") == pytest.approx(width["elbow_joint"])
    # predict reloads it; the first 1.4 s are at rest: residual within 2x the torque noise
    r = CliRunner().invoke(app, ["predict", "--robot", "ur10", "--model", str(out), "--data", str(d / "b.csv"),
                                 "--trim", "0:1.4", "--out", str(tmp_path / "idle.npz")])
    assert r.exit_code == 0, r.output
    z = np.load(tmp_path / "idle.npz")
    rms = np.sqrt(np.mean((z["tau_measured"] - z["tau_pred"]) ** 2, axis=0))
    assert np.all(rms <= 2.0 * K * 0.01), rms / (K * 0.01)
    sgn = st.__class__(robot, joint_terms=st.per_joint_terms, coulomb_smoothing=0.0,
                       stribeck_velocity=st.stribeck_velocity)
    te = load_log(d / "b.csv", robot, COLS, None, 5.0, 21, 1, gains=str(d / "gains.json"), trim="0:1.4", rest="off")
    rms_sgn = np.sqrt(np.mean((sgn.target(te) - sgn.torques(p, te)) ** 2, axis=0))
    assert np.max(rms_sgn / (K * 0.01)) > 5  # sgn(v) would chatter at rest


def test_drive_gains_from_a_pair_within_2_percent_and_cli_output_is_a_gains_file(ur10_logs, tmp_path):
    d, robot, truth, K = ur10_logs
    u, lo = (load_log(d / f, robot, COLS, None, None, 21, 1, trim="1.5:-1") for f in ("u.csv", "l.csv"))
    calls = []
    res = identify_drive_gains(robot, u, lo, payload_mass=4.0, payload_frame="tool0", payload_com=(0.06, 0.02, 0.05),
                               n_boot=250, progress=lambda *a: calls.append(a))
    assert calls == [(100, 250), (200, 250), (250, 250)]
    assert np.all(np.abs(res.gains / K - 1) < 0.02), res.gains / K
    assert res.identified.all() and np.all(res.std > 0)
    used = res.diagnostics["samples_used"]  # samples near velocity reversals are left out, per joint
    assert all(0.5 * res.diagnostics["n_samples"] < used[j] < res.diagnostics["n_samples"] for j in robot.actuated_joints)
    out = tmp_path / "k.json"
    r = CliRunner().invoke(app, ["drive-gains", "--robot", "ur10", "--unloaded", str(d / "u.csv"), "--loaded",
                                 str(d / "l.csv"), "--columns", COLS, "--trim", "1.5:-1", "--savgol-window", "21",
                                 "--payload-mass", "4", "--frame", "tool0", "--com", "0.06,0.02,0.05", "--n-boot", "100",
                                 "--out", str(out)])
    assert r.exit_code == 0, r.output
    from sensorless.data.gains import resolve_gains

    assert np.allclose(resolve_gains(out, robot.actuated_joints), json.loads(out.read_text())["estimated_gains"]
                       and [json.loads(out.read_text())["gains"][j] for j in robot.actuated_joints])
    # a payload on the last joint's axis does not see its gain: a typed error naming the joint, no output
    r = CliRunner().invoke(app, ["drive-gains", "--robot", "ur10", "--unloaded", str(d / "u.csv"), "--loaded",
                                 str(d / "u.csv"), "--columns", COLS, "--payload-mass", "4", "--frame", "tool0",
                                 "--n-boot", "20", "--out", str(tmp_path / "bad.json")])
    assert r.exit_code == 2 and "--nominal-gains" in r.output and not (tmp_path / "bad.json").exists()


def test_default_derivative_window_is_0_2_seconds_and_odd():
    from sensorless.data.filtering import default_savgol_window

    assert default_savgol_window(100.0) == 21 and default_savgol_window(1000.0) == 201
    assert default_savgol_window(50.0) == 11 and default_savgol_window(float("nan")) == 11  # at least 11
    assert all(default_savgol_window(r) % 2 == 1 for r in (30.0, 99.0, 125.0, 333.0))


def test_rest_detection_zeroes_a_joint_at_rest_but_not_a_reversal():
    from sensorless.data import Trajectory
    from sensorless.data.prepare import prepare

    rng = np.random.default_rng(0)
    rate, sig = 100.0, 1e-3
    t = np.arange(1000) / rate
    moving = t >= 3.0
    v_true = np.where(moving, 0.5 * np.sin(2 * np.pi * 0.5 * (t - 3.0)), 0.0)  # rest 3 s, then reversals
    q_true = np.cumsum(v_true) / rate
    v = np.column_stack([v_true, np.zeros_like(t)]) + rng.normal(0, sig, (len(t), 2))  # joint 2 always at rest
    q = np.column_stack([q_true, np.zeros_like(t)])
    traj = Trajectory(t=t, q=q, v=v, tau=np.zeros_like(q), joint_names=("j1", "j2"))
    out = prepare(traj)
    info = out.provenance["rest"]
    assert abs(info["velocity_noise"]["j1"] / sig - 1) < 0.15  # the white-noise estimate
    assert np.all(out.v[t < 2.8, 0] == 0) and np.all(out.a[t < 2.8, 0] == 0) and np.all(out.v[:, 1] == 0)
    near_reversal = moving & (np.abs(v_true) < 0.05) & (t > 3.5)
    assert near_reversal.sum() > 10 and np.all(out.v[near_reversal, 0] != 0)  # a reversal is motion
    assert info["fraction_at_rest"]["j2"] == 1.0 and 0.25 < info["fraction_at_rest"]["j1"] < 0.32
    assert np.array_equal(prepare(traj, rest="off").v, traj.v)  # off: the logged v as it is
    with pytest.raises(Exception, match="`rest` must be one of"):
        prepare(traj, rest="sometimes")


def test_payload_with_every_joint_set_aside_is_no_svd_crash():
    """Regression (issue 17): payload with nominal, wrong gains raised 'LinAlgError: SVD did not
    converge' once every joint had been set aside as contradicting (zero weights -> NaN system)."""
    from sensorless.identification.payload_fit import PayloadSolver, solve_without

    A = np.eye(10)[None].repeat(3, axis=0) * np.arange(1.0, 4.0)[:, None, None]
    A = np.concatenate([np.concatenate([A, np.zeros((3, 10, 1))], 2),
                        np.concatenate([np.zeros((3, 1, 10)), np.ones((3, 1, 1))], 2)], 1)  # 11x11 with an offset
    b = np.ones((3, 11))
    solver = PayloadSolver("full", False, None)
    assert solve_without(solver, A, b, np.zeros(3), np.ones(3, bool)) is None
    phi = solve_without(solver, A, b, np.array([1.0, 0.0, 1.0]), np.ones(3, bool))
    assert phi is not None and np.all(np.isfinite(phi))


def test_predict_applies_the_models_rest_setting(ur10_logs, tmp_path):
    """A model identified with --rest off is predicted without rest detection (it chatters at
    rest through sgn(noise)); the default model does not (test above)."""
    d, robot, truth, K = ur10_logs
    out = tmp_path / "m_off"
    r = CliRunner().invoke(app, ["identify", "--robot", "ur10", "--data", str(d / "a.csv"), "--columns", COLS,
                                 "--gains", str(d / "gains.json"), "--rest", "off", "--coulomb-smoothing", "0",
                                 "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert json.loads((out / "result.json").read_text())["settings"]["preprocessing"]["rest"] == "off"
    r = CliRunner().invoke(app, ["predict", "--robot", "ur10", "--model", str(out), "--data", str(d / "b.csv"),
                                 "--trim", "0:1.4", "--out", str(tmp_path / "idle.npz")])
    assert r.exit_code == 0, r.output
    z = np.load(tmp_path / "idle.npz")
    rms = np.sqrt(np.mean((z["tau_measured"] - z["tau_pred"]) ** 2, axis=0))
    assert np.max(rms / (K * 0.01)) > 5
    r = CliRunner().invoke(app, ["identify", "--robot", "ur10", "--data", str(d / "a.csv"), "--columns", COLS,
                                 "--rest", "never", "--out", str(tmp_path / "bad")])
    assert r.exit_code != 0 and "--rest" in r.output and not (tmp_path / "bad").exists()


def test_clock_offset_between_two_runs_is_found_from_the_positions():
    """Two runs of one trajectory, each stamped from its own first sample, are off by that
    sample's jitter; a 3 ms offset biased shoulder gains by ~1 % before the runs were aligned."""
    from sensorless.data import Trajectory
    from sensorless.data.align import clock_offset

    t = np.arange(2000) / 100.0
    f = lambda s: np.column_stack([np.sin(0.7 * s), 0.5 * np.cos(1.3 * s)])  # noqa: E731
    df = lambda s: np.column_stack([0.7 * np.cos(0.7 * s), -0.65 * np.sin(1.3 * s)])  # noqa: E731
    ref = Trajectory(t=t, q=f(t), v=df(t), tau=np.zeros((2000, 2)), joint_names=("a", "b"))
    rng = np.random.default_rng(1)
    load = Trajectory(t=t + 50.0, q=f(t + 0.003) + rng.normal(0, 1e-4, (2000, 2)), v=df(t + 0.003),
                      tau=np.zeros((2000, 2)), joint_names=("a", "b"))
    assert clock_offset(load, ref) == pytest.approx(0.003, abs=1e-4)
    assert clock_offset(ref, ref) == pytest.approx(0.0, abs=1e-9)


def _single_joint_logs(panda):
    """One log per joint, only that joint moving (its encoder velocity noisy, the others' v ≡ 0)."""
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    truth = perturbed_truth(panda, rng=0)
    rng = np.random.default_rng(3)
    logs = []
    for k in range(len(panda.joint_names)):
        m = random_fourier(panda, rng=10 + k, base_freq=0.2).sample(100, 8.0)
        q, v, a = m.q.copy(), np.zeros_like(m.v), np.zeros_like(m.a)
        still = [j for j in range(q.shape[1]) if j != k]
        q[:, still] = q[0, still]
        v[:, k], a[:, k] = m.v[:, k], m.a[:, k]
        tr = synthetic_trajectory(truth, m.with_(q=q, v=v, a=a), noise_std=0.05, rng=k)
        v_noisy = v.copy()
        v_noisy[:, k] += rng.normal(0, 0.01, len(v))  # the moving joint's encoder velocity is noisy
        logs.append(tr.with_(v=v_noisy))
    return logs


def test_coulomb_smoothing_per_joint_from_the_logs_where_it_moves(panda):
    """Six single-joint calibration logs (real-log issue): each joint's ε comes from the log where it
    moves. Pooled over every log (or read from the first log only) the still joints' v ≡ 0 pulled
    ε to 0 and Coulomb friction collapsed into viscous."""
    from sensorless.identification.friction import friction_structure

    logs = _single_joint_logs(panda)
    s = ModelStructure(panda, joint_terms=("fv", "fc"))
    _, together = friction_structure(s, logs)
    for k, j in enumerate(panda.actuated_joints):
        _, alone = friction_structure(s, [logs[k]])
        assert together.coulomb_smoothing[j] > 1e-3, together.coulomb_smoothing
        assert together.coulomb_smoothing[j] == pytest.approx(alone.coulomb_smoothing[j], rel=0.05)


def test_cli_single_joint_logs_give_every_joint_its_own_coulomb_smoothing(panda, tmp_path):
    from sensorless.data import write_npz

    paths = [write_npz(t, tmp_path / f"j{k}.npz") for k, t in enumerate(_single_joint_logs(panda))]
    r = CliRunner().invoke(app, ["identify", "--robot", "panda", "--lock", "panda_finger_joint1", "--lock",
                                 "panda_finger_joint2", "--data", *map(str, paths), "--method", "lmi", "--gamma", "1e-2",
                                 "--joint-terms", "fv,fc", "--no-plot", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    fr = json.loads((tmp_path / "m" / "result.json").read_text())["settings"]["friction"]
    assert min(fr["coulomb_smoothing"].values()) > 1e-3, fr["coulomb_smoothing"]
    assert len(fr["coulomb_smoothing_from"]) == len(paths)  # every log, since the first leaves joints still
