"""Collision detection: thresholds from a quiet segment, intervals, and `sensorless monitor`."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.errors import DataError
from sensorless.estimation.collision import detect_contacts, quiet_mask, quiet_thresholds, score_detection
from sensorless.robot import load_robot
from sensorless_studies.simulation.arm_push import pushed_arm_scenario


def test_false_alarm_rate_threshold_on_white_noise():
    """k from a target false-alarm rate: on white noise the realised rate stays at or below it,
    and a step of 10 σ is detected at its first sample."""
    rng = np.random.default_rng(0)
    dt, n = 1e-3, 600_000  # 10 minutes
    t = np.arange(n) * dt
    r = rng.normal(size=(n, 3)) * [1.0, 0.1, 5.0] + [0.5, 0.0, -1.0]
    th = quiet_thresholds(r, t < 60.0, ["a", "b", "c"], false_alarm_rate=2.0, dt=dt)
    assert 4.0 < th.k < 6.0
    np.testing.assert_allclose(th.sigma, [1.0, 0.1, 5.0], rtol=0.02)
    _, ivs = detect_contacts(r, t, th)
    rate = len(ivs) / (n * dt / 60)
    assert rate <= 2.0 * 1.5
    truth = np.zeros(n, bool)
    truth[300_000:300_500] = True
    r[truth, 1] += 1.0
    _, ivs = detect_contacts(r, t, th)
    score = score_detection(ivs, t, truth)
    assert score["detected"] == 1 and score["mean_delay_s"] <= dt


def test_threshold_input_errors():
    t = np.arange(100) * 0.01
    r = np.zeros((100, 2))
    with pytest.raises(DataError, match="quiet segment 5:6"):
        quiet_mask(t, "5:6", "log.csv")
    with pytest.raises(DataError, match="exactly one"):
        quiet_thresholds(r, t < 0.5, ["a", "b"])
    with pytest.raises(DataError, match="20 samples|need ≥ 20"):
        quiet_thresholds(r, t < 0.05, ["a", "b"], k=3.0)


@pytest.fixture(scope="module")
def arm_logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("monitor")
    train, log, gt = pushed_arm_scenario(0)
    write_npz(train, d / "train.npz")
    write_npz(log, d / "pushed.npz")
    res = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(d / "train.npz"), "--out", str(d / "id"),
                                   "--coulomb-smoothing", "0.05"])
    assert res.exit_code == 0, res.output
    return d, gt


def test_monitor_cli_finds_the_pushes(arm_logs):
    d, gt = arm_logs
    runner = CliRunner()
    res = runner.invoke(app, ["monitor", "--robot", "ur5", "--model", str(d / "id"), "--data", str(d / "pushed.npz"),
                              "--frame", "tool0", "--quiet", "0:10", "--out", str(d / "mon")])
    assert res.exit_code == 0, res.output
    doc = json.loads((d / "mon" / "monitor.json").read_text())
    ivs = doc["contacts"]
    assert len(ivs) == 2, ivs
    for iv, push in zip(ivs, gt.pushes):
        assert push.start <= iv["start"] <= push.end and iv["end"] <= push.end + 0.2
        assert abs(iv["peak_force_norm"] - np.linalg.norm(push.peak)) < 0.3 * np.linalg.norm(push.peak)
        # estimate-force's convention: the force the robot exerts on its environment, i.e. minus the push
        assert np.dot(iv["peak_force"], push.peak) < -0.8 * np.linalg.norm(push.peak) * iv["peak_force_norm"]
    arrays = np.load(d / "mon" / "monitor.npz")
    assert arrays["tau_ext"].shape == (len(gt.t), 6) and arrays["force"].shape == (len(gt.t), 3)
    # the same log through estimate-force: the same force, sign included, during the first push
    out = d / "force.npz"
    res = runner.invoke(app, ["estimate-force", "--robot", "ur5", "--model", str(d / "id"), "--data",
                              str(d / "pushed.npz"), "--frame", "tool0", "--out", str(out)])
    assert res.exit_code == 0, res.output
    ef = np.load(out)
    push = gt.pushes[0]
    i = int(np.argmin(np.abs(gt.t - 0.5 * (push.start + push.end))))
    assert np.dot(ef["force"][i], arrays["force"][i]) > 0 and np.dot(ef["force"][i], push.peak) < 0
    assert set(doc["peak_external_torque"]) == set(load_robot("ur5").joint_names)


def test_monitor_cli_bad_quiet_leaves_no_output(arm_logs):
    d, _ = arm_logs
    runner = CliRunner()
    cases = [(["--quiet", "3"], "START:END"), (["--quiet", "50:60"], "holds 0 samples"),
             (["--quiet", "abs:100:101"], "abs:100:101 = 100..101 s after the first sample holds 0 samples"),
             (["--static-friction", "1,2"], "6 values in joint order"),
             (["--static-friction", "elbow_joint=1"], "give every joint or a default '*=VALUE'"),
             (["--static-friction", "nope=1,*=2"], "not monitored"), (["--static-friction", "-1"], "≥ 0 N·m"),
             (["--rest-speed", "fast"], "--rest-speed must be 'auto'"), (["--static-margin", "-0.1"], "--static-margin"),
             (["--warmup", "-1"], "--warmup")]
    for extra, msg in cases:
        res = runner.invoke(app, ["monitor", "--robot", "ur5", "--model", str(d / "id"), "--data", str(d / "pushed.npz"),
                                  *extra, "--out", str(d / "bad")])
        assert res.exit_code == 2 and msg in res.output.replace("\n", " "), res.output
        assert not (d / "bad").exists()


def test_monitor_cli_on_a_current_logged_arm_with_a_gains_map(arm_logs):
    """The pushed log as a CSV of motor currents i = τ/K plus a gains file: monitor maps it
    through τ = K·i and finds the same two pushes."""
    import pandas as pd

    d, gt = arm_logs
    log = np.load(d / "pushed.npz")
    log = {"t": log["times"], "q": log["positions"], "v": log["velocities"], "tau": log["torques"]}
    names = load_robot("ur5").joint_names
    gains = np.linspace(8.0, 12.0, len(names))
    cols = {"time": log["t"]}
    cols.update({f"pos_{n}": log["q"][:, j] for j, n in enumerate(names)})
    cols.update({f"vel_{n}": log["v"][:, j] for j, n in enumerate(names)})
    cols.update({f"i_{n}": log["tau"][:, j] / gains[j] for j, n in enumerate(names)})
    pd.DataFrame(cols).to_csv(d / "pushed_currents.csv", index=False)
    (d / "gains.json").write_text(json.dumps(dict(zip(names, map(float, gains)))))
    res = CliRunner().invoke(app, ["monitor", "--robot", "ur5", "--model", str(d / "id"),
                                   "--data", str(d / "pushed_currents.csv"),
                                   "--columns", "q=pos_{joint};v=vel_{joint};tau=i_{joint}",
                                   "--gains", str(d / "gains.json"), "--frame", "tool0", "--quiet", "0:10",
                                   "--out", str(d / "mon_currents")])
    assert res.exit_code == 0, res.output
    ivs = json.loads((d / "mon_currents" / "monitor.json").read_text())["contacts"]
    assert len(ivs) == 2, ivs
    for iv, push in zip(ivs, gt.pushes):
        assert push.start <= iv["start"] <= push.end


def test_monitor_png_draws_tau_ext_its_threshold_and_the_contacts(arm_logs, monkeypatch):
    """monitor.png (issue 24): per joint τ_ext [N·m] with the two threshold lines, the no-contact band, and one
    shaded span per reported contact at its times; --no-plot writes none."""
    import sensorless.report.monitor_plot as mp

    from sensorless.report.figure_kit import save_figure

    d, gt = arm_logs
    saved = {}
    monkeypatch.setattr(mp, "save_figure", lambda fig, path: saved.setdefault(path.name, fig) and save_figure(fig, path))
    res = CliRunner().invoke(app, ["monitor", "--robot", "ur5", "--model", str(d / "id"), "--data", str(d / "pushed.npz"),
                                   "--quiet", "0:10", "--out", str(d / "mon_png")])
    assert res.exit_code == 0, res.output
    assert (d / "mon_png" / "monitor.png").stat().st_size > 10_000
    doc = json.loads((d / "mon_png" / "monitor.json").read_text())
    arrays = np.load(d / "mon_png" / "monitor.npz")
    fig = saved["monitor.png"]
    names = load_robot("ur5").joint_names
    assert [a.get_title(loc="left").split()[0] for a in fig.axes] == list(names)
    t0 = arrays["t"][0]
    for ax in fig.axes:
        assert ax.get_ylabel() == "τ_ext [N·m]"
        assert len([ln for ln in ax.get_lines() if ln.get_gid() == "threshold"]) == 2
        assert [c.get_gid() for c in ax.collections].count("no_contact_band") == 1
        (spans,) = [c for c in ax.collections if c.get_gid() == "contact"]
        xs = [(p.vertices[:, 0].min(), p.vertices[:, 0].max()) for p in spans.get_paths()]
        np.testing.assert_allclose(xs, [(c["start"] - t0, c["end"] - t0) for c in doc["contacts"]])
        assert len(xs) == len(gt.pushes) == 2
    assert fig.axes[-1].get_xlabel() == "time [s]"
    labels = [x.get_text() for x in fig.legends[0].get_texts()]
    assert {"contact threshold", "no-contact band", "contact (reported) (2)"} <= set(labels)
    # the threshold lines are where τ_ext turns into a contact: the push peak lies outside them, on its joint
    ax = fig.axes[1]  # shoulder_lift_joint: pushed by the first (vertical) push
    tau = next(ln for ln in ax.get_lines() if ln.get_gid() == "tau_ext")
    lo, hi = (ln.get_ydata() for ln in ax.get_lines() if ln.get_gid() == "threshold")
    assert np.nanmax(np.abs(tau.get_ydata())) == pytest.approx(np.nanmax(np.abs(arrays["tau_ext"][:, 1])))  # peak kept
    k = np.nanargmax(np.abs(tau.get_ydata()))
    assert not lo[k] <= tau.get_ydata()[k] <= hi[k]
    res = CliRunner().invoke(app, ["monitor", "--robot", "ur5", "--model", str(d / "id"), "--data", str(d / "pushed.npz"),
                                   "--quiet", "0:10", "--no-plot", "--out", str(d / "mon_noplot")])
    assert res.exit_code == 0 and not list((d / "mon_noplot").glob("*.png"))


def test_estimate_force_png_next_to_the_npz(arm_logs, monkeypatch):
    """estimate-force writes f.png next to f.npz (fx, fy, fz [N] against time [s]); --no-plot writes none."""
    import sensorless.report.force_plot as fp

    from sensorless.report.figure_kit import save_figure

    d, _ = arm_logs
    saved = {}
    monkeypatch.setattr(fp, "save_figure", lambda fig, path: saved.setdefault(path.name, fig) and save_figure(fig, path))
    args = ["estimate-force", "--robot", "ur5", "--model", str(d / "id"), "--data", str(d / "pushed.npz"),
            "--frame", "tool0"]
    res = CliRunner().invoke(app, [*args, "--out", str(d / "f_png.npz")])
    assert res.exit_code == 0, res.output
    assert (d / "f_png.png").stat().st_size > 10_000 and "f_png.png" in res.output.replace("\n", "")
    fig = saved["f_png.png"]
    assert [a.get_ylabel() for a in fig.axes] == ["fx [N]", "fy [N]", "fz [N]"]
    assert fig.axes[-1].get_xlabel() == "time [s]"
    ef = np.load(d / "f_png.npz")
    line = next(ln for ln in fig.axes[2].get_lines() if ln.get_gid() == "force")
    assert np.nanmax(np.abs(line.get_ydata())) == pytest.approx(np.nanmax(np.abs(ef["force"][:, 2])))  # peaks kept
    res = CliRunner().invoke(app, [*args, "--no-plot", "--out", str(d / "f_none.npz")])
    assert res.exit_code == 0 and (d / "f_none.npz").exists() and not (d / "f_none.png").exists()
