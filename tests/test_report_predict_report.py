"""`sensorless predict` draws its fit (issue 42): OUT.png (measured against predicted with the residual,
per joint, with units) and OUT.html (the metrics, joints at rest with RMSE and bias, the figure and the
run's warnings), unless --no-plot; the predictions file is unchanged."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.excitation import random_fourier
from sensorless.robot import load_robot
from sensorless.testing import RealArtefacts, perturbed_truth, synthetic_trajectory, with_real_artefacts


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """A UR5 model and a held-out log whose wrist_3 is held still (holding torque at rest)."""
    d = tmp_path_factory.mktemp("predict")
    ur5 = load_robot("ur5")
    truth = perturbed_truth(ur5, rng=0)
    tr = synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(200.0, 8.0), noise_std=0.1, rng=2)
    te = random_fourier(ur5, rng=3).sample(200.0, 5.0)
    q = te.q.copy()
    q[:, 5] = q[0, 5]  # wrist_3 held
    v, a = te.v.copy(), te.a.copy()
    v[:, 5] = a[:, 5] = 0.0
    te = synthetic_trajectory(truth, te.with_(q=q, v=v, a=a), noise_std=0.1, rng=4)
    te = with_real_artefacts(te, RealArtefacts(decimals=4, holding=0.3), rng=5, joints=["wrist_3_joint"])
    write_npz(tr, d / "train.npz")
    write_npz(te, d / "test.npz")
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(d / "train.npz"), "--method", "ols",
                                 "--no-plot", "--out", str(d / "m")])
    assert r.exit_code == 0, r.output
    return d


def test_predict_writes_the_figure_and_the_page(folder, tmp_path):
    out = tmp_path / "pred.npz"
    r = CliRunner().invoke(app, ["predict", "--robot", "ur5", "--model", str(folder / "m"),
                                 "--data", str(folder / "test.npz"), "--out", str(out)])
    text = " ".join(r.output.split())
    assert r.exit_code == 0, r.output
    assert "wrist_3_joint (at rest)" in text and "N·m rms, bias" in text, text  # held pose: RMSE and bias
    png, html = tmp_path / "pred.png", tmp_path / "pred.html"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = html.read_text()
    assert "at rest, bias" in page and "RMSE [N·m]" in page and "data:image/png;base64," in page
    assert "shoulder_pan_joint" in page and "identified (ols)" in page
    np.testing.assert_array_equal(np.load(out)["joints"], load_robot("ur5").joint_names)


def test_the_figure_has_units_and_a_residual_per_joint(folder):
    from sensorless.report.plots import torque_figure

    ur5 = load_robot("ur5")
    t = np.linspace(0, 1, 50)
    y = np.zeros((50, 6))
    fig = torque_figure(t, y, {"model": y + 0.1}, list(ur5.joint_names), robot=ur5, title="x")
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels.count("torque [N·m]") == 6 and labels.count("residual [N·m]") == 6
    assert sum(ax.get_xlabel() == "time [s]" for ax in fig.axes) == 2  # the bottom of each column


def test_no_plot_writes_only_the_predictions(folder, tmp_path):
    out = tmp_path / "p.npz"
    r = CliRunner().invoke(app, ["predict", "--robot", "ur5", "--model", str(folder / "m"),
                                 "--data", str(folder / "test.npz"), "--out", str(out), "--no-plot"])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.npz"]


def test_an_existing_figure_is_not_overwritten_without_force(folder, tmp_path):
    (tmp_path / "p.png").write_bytes(b"mine")
    args = ["predict", "--robot", "ur5", "--model", str(folder / "m"), "--data", str(folder / "test.npz"),
            "--out", str(tmp_path / "p.npz")]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 2 and "p.png" in r.output and (tmp_path / "p.png").read_bytes() == b"mine"
    assert not (tmp_path / "p.npz").exists()
    assert CliRunner().invoke(app, [*args, "--force"]).exit_code == 0
