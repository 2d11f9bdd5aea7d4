"""`sensorless friction` on bench CSV logs with irregular steps and a gap, and the friction-only
model in `predict` (no --robot) and `monitor`."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.errors import ParameterError
from sensorless.identification.artifact import load_friction_model, load_model_folder
from sensorless_studies.simulation.lugre import LuGreJoint, lugre_friction, simulate_lugre_joint, velocity_profile, write_bench_csv

runner = CliRunner()
LUGRE, STATIC = LuGreJoint(), LuGreJoint(sigma0=None)


def _two_joint_csv(path, duration, seed, gap=None, duplicate=None):
    """Joint 'slide' with LuGre friction and joint 'plain' without presliding, on the same irregular
    stamps (jitter ±30 %), optionally without the samples in ``gap`` [s] and with row ``duplicate`` twice."""
    prof = velocity_profile(duration, seed)
    a, _ = simulate_lugre_joint(LUGRE, duration=duration, seed=seed, profile=prof)
    b, _ = simulate_lugre_joint(STATIC, duration=duration, seed=seed, profile=prof)
    df = pd.DataFrame({"time": a.t, "q_slide": a.q[:, 0], "v_slide": a.v[:, 0], "tau_slide": a.tau[:, 0],
                       "q_plain": b.q[:, 0], "v_plain": b.v[:, 0], "tau_plain": b.tau[:, 0]})
    if gap is not None:
        df = df[(df.time < gap[0]) | (df.time > gap[1])]
    if duplicate is not None:
        df = pd.concat([df.iloc[:duplicate + 1], df.iloc[duplicate:]])
    df.to_csv(path, index=False, float_format="%.9g")
    return prof


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    d = tmp_path_factory.mktemp("bench")
    _two_joint_csv(d / "train.csv", 60.0, 0, gap=(20.0, 20.6), duplicate=500)
    prof = _two_joint_csv(d / "test.csv", 40.0, 21, gap=(10.0, 10.4))
    r = runner.invoke(app, ["friction", "--data", str(d / "train.csv"), "--test", str(d / "test.csv"),
                            "--out", str(d / "model")])
    assert r.exit_code == 0, r.output
    return d, prof, r.output


def test_friction_command_keeps_the_state_where_it_is_and_halves_the_error_near_reversals(bench):
    d, _, output = bench
    doc = json.loads((d / "model" / "result.json").read_text())
    assert doc["kind"] == "friction" and doc["joints"] == ["slide", "plain"]
    assert doc["laws"]["slide"]["kind"] == "state" and doc["laws"]["plain"]["kind"] == "static"
    val = doc["validation"][str(d / "test.csv")]
    assert val["slide"]["model"]["rmse_reversals"] <= 0.5 * val["slide"]["static"]["rmse_reversals"]
    assert doc["diagnostics"]["plain"]["bic"]["state"] > doc["diagnostics"]["plain"]["bic"]["static"]
    for j in ("slide", "plain"):
        assert all(iv is None or iv[0] <= doc["laws"][j]["coef"][t] <= iv[1]
                   for t, iv in doc["diagnostics"][j]["intervals"].items())
    # the irregular steps and the gap were kept, not refused or resampled
    signals = doc["settings"]["signals"][str(d / "train.csv")]["bench"]
    assert signals["irregular"] and signals["n_gaps"] == 1 and signals["gaps"][0][0] < 20.0 < signals["gaps"][0][1]
    assert doc["settings"]["preprocessing"]["max_gap"] == 10.0
    rows = len(pd.read_csv(d / "train.csv"))
    assert doc["diagnostics"]["slide"]["n_samples"] == rows - 1  # every sample, the duplicate stamp merged
    assert (d / "model" / "friction.png").stat().st_size > 0
    assert "state" in output and "near reversals" in output


def test_predict_carries_the_state_without_a_robot(bench, tmp_path):
    d, prof, _ = bench
    out = tmp_path / "p.npz"
    r = runner.invoke(app, ["predict", "--model", str(d / "model"), "--data", str(d / "test.csv"), "--out", str(out)])
    assert r.exit_code == 0, r.output
    z = np.load(out)
    assert list(z["joints"]) == ["slide", "plain"] and "tau_pred_static" in z.files
    t = z["t"]
    truth = lugre_friction(LUGRE, prof, t)[0] + LUGRE.inertia * prof(t)[2]  # the simulated joint, noise-free
    rms = lambda x: float(np.sqrt(np.mean(x**2)))  # noqa: E731
    assert rms(z["tau_pred"][:, 0] - truth) <= 0.5 * rms(z["tau_pred_static"][:, 0] - truth)
    art = load_friction_model(d / "model")
    assert art.model.laws_["slide"].kind == "state"


def test_single_joint_bare_columns_position_only_irregular_steps(tmp_path):
    tr, _ = simulate_lugre_joint(LUGRE, duration=30.0, seed=5)
    write_bench_csv(tr, tmp_path / "bench.csv", velocity=False)  # t, q, tau: v and v̇ from q
    r = runner.invoke(app, ["friction", "--data", str(tmp_path / "bench.csv"), "--joints", "motor",
                            "--out", str(tmp_path / "m"), "--no-plot"])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "m" / "result.json").read_text())
    assert doc["joints"] == ["motor"] and doc["laws"]["motor"]["kind"] == "state"
    assert "d/dt q" in doc["settings"]["signals"][str(tmp_path / "bench.csv")]["v"]


def test_motor_currents_with_gains(tmp_path):
    tr, _ = simulate_lugre_joint(STATIC, duration=20.0, seed=6)
    pd.DataFrame({"time": tr.t, "position": tr.q[:, 0], "velocity": tr.v[:, 0],
                  "current": tr.tau[:, 0] / 2.5}).to_csv(tmp_path / "cur.csv", index=False)
    r = runner.invoke(app, ["friction", "--data", str(tmp_path / "cur.csv"), "--gains", "2.5", "--state", "off",
                            "--no-plot", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "m" / "result.json").read_text())
    assert doc["laws"]["joint"]["coef"]["fc"] == pytest.approx(STATIC.fc, rel=0.05)


def test_monitor_with_a_friction_model_finds_a_push(bench, tmp_path):
    d, _, _ = bench
    a, _ = simulate_lugre_joint(LUGRE, duration=20.0, seed=8, jitter=0.0, joint="slide")
    b, _ = simulate_lugre_joint(STATIC, duration=20.0, seed=8, jitter=0.0, joint="plain",
                                profile=velocity_profile(20.0, 8))
    push = np.where((a.t > 12) & (a.t < 14), 0.3, 0.0)
    pd.DataFrame({"time": a.t, "q_slide": a.q[:, 0], "v_slide": a.v[:, 0], "tau_slide": a.tau[:, 0] - push,
                  "q_plain": b.q[:, 0], "v_plain": b.v[:, 0], "tau_plain": b.tau[:, 0]}).to_csv(tmp_path / "m.csv",
                                                                                                index=False)
    r = runner.invoke(app, ["monitor", "--model", str(d / "model"), "--data", str(tmp_path / "m.csv"),
                            "--out", str(tmp_path / "mon"), "--quiet", "0:8", "--gain", "20"])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "mon" / "monitor.json").read_text())
    hits = [c for c in doc["contacts"] if c["start"] < 13.0 and c["end"] > 13.5 and "slide" in c["joints"]]
    assert hits and doc["robot"] is None


def test_friction_model_errors_are_one_line(bench, tmp_path):
    d, _, _ = bench
    with pytest.raises(ParameterError, match="friction-only model"):
        load_model_folder(d / "model", None)
    bad = tmp_path / "bad"
    bad.mkdir()
    doc = json.loads((d / "model" / "result.json").read_text())
    doc["laws"]["slide"]["k"] = -1.0
    (bad / "result.json").write_text(json.dumps(doc))
    r = runner.invoke(app, ["predict", "--model", str(bad), "--data", str(d / "test.csv"), "--out", str(tmp_path / "p.npz")])
    assert r.exit_code == 2 and "laws.slide.k" in r.output and len(r.output.strip().splitlines()) == 1
    r = runner.invoke(app, ["predict", "--model", str(d / "model"), "--data", str(d / "test.csv"), "--lowpass", "5",
                            "--out", str(tmp_path / "p.npz")])
    assert r.exit_code == 2 and "--lowpass" in r.output
    back = tmp_path / "back.csv"
    rows = pd.read_csv(d / "test.csv")
    rows.loc[100, "time"] = rows.loc[98, "time"]
    rows.to_csv(back, index=False)
    r = runner.invoke(app, ["friction", "--data", str(back), "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "sample 100" in r.output and not (tmp_path / "o").exists()
    r = runner.invoke(app, ["friction", "--data", str(d / "test.csv"), "--terms", "fv,offset",
                            "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "fc" in r.output


def test_bench_friction_png_has_units_residuals_and_the_state_law_closer_at_the_reversal(bench):
    """friction.png of `sensorless friction` (issue 24): per joint three panels with units, each with its
    residual below, one legend above; at the first reversal the state law's residual is the smaller one."""
    from sensorless.cli.friction import friction_model_log
    from sensorless.report.friction_bench_plot import bench_friction_figure

    d, _, _ = bench
    art, log, _ = friction_model_log(d / "model", d / "test.csv", {})
    fig = bench_friction_figure(art.model, [log], title="held-out log")
    axes = fig.axes
    assert len(axes) == 2 * 3 * 2  # 2 joints × 3 panels × (signal, residual)
    pairs = list(zip(axes[0::2], axes[1::2]))
    for k, (a, b) in enumerate(pairs):
        u = "N·m"
        assert b.get_ylabel() == f"residual [{u}]"
        assert a.get_ylabel() == (f"τ [{u}]" if k % 3 == 2 else f"friction [{u}]")
        assert b.get_xlabel() == ("time [s]" if k % 3 == 2 else "v [rad/s]")
    assert len(fig.legends) == 1 and all(a.get_legend() is None for a in axes)
    rev = pairs[2][1]  # slide: residuals at its first reversal, chosen (state) law then the static law
    state, static = (ln.get_ydata() for ln in rev.get_lines()[1:3])
    assert np.sqrt(np.mean(state**2)) < 0.5 * np.sqrt(np.mean(static**2))


@pytest.mark.parametrize("corrupt", ["zero", "constant", "sign"])
def test_zero_constant_or_sign_flipped_torque_refused(bench, tmp_path, corrupt):
    """Issue #41 reproducer: `friction` fitted zero, constant and sign-flipped torques (exit 0, a law of 0 or a
    negative one). A moving joint's torque must vary and dissipate (mean τ·v > 0)."""
    d, _, _ = bench
    df = pd.read_csv(d / "train.csv")
    df["tau_plain"] = {"zero": 0.0 * df.tau_plain, "constant": 0 * df.tau_plain + 1.5, "sign": -df.tau_plain}[corrupt]
    df.to_csv(tmp_path / "bad.csv", index=False, float_format="%.9g")
    r = runner.invoke(app, ["friction", "--data", str(tmp_path / "bad.csv"), "--out", str(tmp_path / "m")])
    line = " ".join(r.output.split())
    assert r.exit_code == 2 and "tau[plain]" in line and ("constant" in line or "sign is flipped" in line), line
    assert not (tmp_path / "m").exists()
