"""`excite` is physical safety (issue 12, High 2): the samples written are checked against the
robot model's limits and the excitation limits, and nonsense options fail before anything
is written.
"""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import read_trajectory
from sensorless.errors import ExcitationError
from sensorless.excitation import FourierTrajectory, random_fourier
from sensorless.excitation import (
    ExcitationDesign,
    ExcitationLimits,
    check_export,
    check_sampled_limits,
    design_excitation,
    robot_limits,
)
from sensorless.regressor import ModelStructure

runner = CliRunner()
PANDA = ["--robot", "panda", "--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]
FAST = ["--harmonics", "2", "--n-samples", "40", "--maxiter", "3"]


def _excite(out, *args):
    return runner.invoke(app, ["excite", *PANDA, *FAST, *map(str, args), "--out", str(out)])


@pytest.mark.parametrize("args, needle", [
    (["--position-fraction", "2"], "--position-fraction"),  # used to drive panda_joint2 to 1.94 rad > 1.76
    (["--position-fraction", "0"], "--position-fraction"),
    (["--position-fraction", "nan"], "--position-fraction"),
    (["--rate", "0"], "--rate"),  # used to write an empty trajectory with exit 0
    (["--rate", "-5"], "--rate"),
    (["--rate", "inf"], "--rate"),
    (["--rate", "1e300"], "--rate"),
    (["--rate", "0.5", "--base-freq", "0.2"], "--rate"),  # 2 harmonics × 0.2 Hz: Nyquist needs > 0.8 Hz
    (["--periods", "-1"], "--periods"),  # used to write an empty trajectory with exit 0
    (["--periods", "0"], "--periods"),
    (["--periods", "1000000", "--rate", "100000"], "samples"),
    (["--base-freq", "0"], "--base-freq"),
    (["--base-freq", "nan"], "--base-freq"),
    (["--max-velocity", "0"], "--max-velocity"),
    (["--max-acceleration", "-1"], "--max-acceleration"),
    (["--max-velocity", "inf"], "--max-velocity"),
    (["--seed", "-1"], "--seed"),
    (["--harmonics", "0"], "--harmonics"),
])
def test_bad_numeric_options_fail_before_writing(tmp_path, args, needle):
    out = tmp_path / "ex"
    r = _excite(out, *args)
    assert r.exit_code == 2, r.output
    text = r.output.strip()
    assert text.startswith("error:") and needle in text.replace("\n", ""), text
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_position_fraction_above_one_is_refused_by_the_library(panda):
    with pytest.raises(ExcitationError, match="position"):
        ExcitationLimits.from_robot(panda, position_fraction=2.0)
    with pytest.raises(ExcitationError, match="position_fraction"):
        random_fourier(panda, position_fraction=2.0)


def test_limits_wider_than_the_robot_are_refused_before_optimising(panda):
    lo, hi = panda.position_limits()
    wide = ExcitationLimits(panda.joint_names, lo, np.where(np.arange(len(hi)) == 1, hi + 0.2, hi), 1.0, 5.0)
    with pytest.raises(ExcitationError, match="panda_joint2"):
        design_excitation(ModelStructure(panda), wide, maxiter=1)


def _violating_design(panda) -> ExcitationDesign:
    """The quoted failure: limits at 2 × the range about mid-range, a trajectory filling them."""
    lo, hi = panda.position_limits()
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    wide = ExcitationLimits(panda.joint_names, mid - 2 * half, mid + 2 * half, 100.0, 1000.0)
    traj = FourierTrajectory(0.1, np.zeros((7, 1)), np.zeros((7, 1)), mid.copy(), tuple(panda.joint_names))
    traj.b[1, 0] = -1.1 * half[1] * 2 * np.pi * 0.1  # joint2 swings to q0 ± 1.1 half-range
    return ExcitationDesign(traj, wide, "cond", {"cond": 1.0}, {"cond": 1.0, "cond_median": 1.0}, {"position": -1.0},
                            hard_limits=robot_limits(panda))


def test_final_samples_are_checked_against_the_robot_and_nothing_is_written(panda, tmp_path):
    design = _violating_design(panda)
    assert max(design.limits.violation(*design.trajectory.evaluate(np.linspace(0, 10, 400))).values()) <= 0  # its own view: fine
    with pytest.raises(ExcitationError) as err:
        design.save(tmp_path / "ex", rate=20.0, periods=1)
    msg = str(err.value)
    _, hi = panda.position_limits()
    assert "panda_joint2" in msg and "robot model" in msg and f"{hi[1]:.6g}" in msg and "sample" in msg
    value = float(msg.split("position ")[1].split()[0])
    assert value > hi[1]
    assert not (tmp_path / "ex").exists()


def test_check_sampled_limits_names_velocity_and_acceleration(panda):
    limits = ExcitationLimits.from_robot(panda, 0.5, 0.5, 1.0)
    traj = random_fourier(panda, rng=0, position_fraction=0.5, max_velocity=0.5, max_acceleration=1.0).sample(50, 10.0)
    excess = check_sampled_limits(traj, limits, robot_limits(panda))
    assert max(excess.values()) <= 1e-9
    fast = traj.with_(v=traj.v * 1.5)
    with pytest.raises(ExcitationError, match="velocity"):
        check_sampled_limits(fast, limits)
    jerky = traj.with_(a=traj.a * 1.5)
    with pytest.raises(ExcitationError, match="acceleration"):
        check_sampled_limits(jerky, limits)
    q = traj.q.copy()
    q[17, 3] = np.nan
    with pytest.raises(ExcitationError, match="panda_joint4, sample 17"):
        check_sampled_limits(traj.with_(q=q), limits)


def test_check_export_counts_samples():
    assert check_export(200.0, 2, 5, 0.1) == 4000
    with pytest.raises(ExcitationError, match="whole number"):
        check_export(200.0, 1.5, 5, 0.1)


def test_cli_full_fraction_stays_inside_the_robot_limits(tmp_path, panda):
    out = tmp_path / "ex"
    r = _excite(out, "--position-fraction", "1", "--rate", "50")
    assert r.exit_code == 0, r.output
    assert "limits respected on the written samples" in r.output
    tr = read_trajectory(out / "trajectory.npz")
    lo, hi = panda.position_limits()
    assert len(tr) == 500
    assert np.all(tr.q >= lo - 1e-9) and np.all(tr.q <= hi + 1e-9)
    assert np.all(np.abs(tr.v) <= panda.velocity_limits() + 1e-9)


def test_excitation_png_draws_the_trajectory_against_its_limits(tmp_path, panda, monkeypatch):
    """excitation.png (issue 24): q [rad], v [rad/s], v̇ [rad/s²] per joint with the excitation limits and the
    robot's own position and velocity limits; the curves drawn are the written samples, inside those lines."""
    import sensorless.report.excitation_plot as xp

    from sensorless.report.figure_kit import save_figure

    saved = {}
    monkeypatch.setattr(xp, "save_figure", lambda fig, path: saved.setdefault(path.name, fig) and save_figure(fig, path))
    out = tmp_path / "ex"
    r = _excite(out, "--rate", "50")
    assert r.exit_code == 0, r.output
    assert (out / "excitation.png").stat().st_size > 10_000
    fig = saved["excitation.png"]
    tr = read_trajectory(out / "trajectory.npz")
    assert len(fig.axes) == 3 * 7
    lo, hi = panda.position_limits()
    for j in range(7):
        axq, axv, axa = fig.axes[3 * j : 3 * j + 3]
        assert (axq.get_ylabel(), axv.get_ylabel(), axa.get_ylabel()) == ("q [rad]", "v [rad/s]", "v̇ [rad/s²]")
        assert axq.get_title(loc="left").startswith(panda.joint_names[j])
        for ax, x in ((axq, tr.q[:, j]), (axv, tr.v[:, j]), (axa, tr.a[:, j])):
            (curve,) = [ln for ln in ax.get_lines() if ln.get_gid() == "trajectory"]
            np.testing.assert_allclose(curve.get_ydata(), x)
            exc = sorted(ln.get_ydata()[0] for ln in ax.get_lines() if ln.get_gid() == "excitation_limit")
            assert len(exc) == 2 and exc[0] <= x.min() and x.max() <= exc[1]
        robot = sorted(ln.get_ydata()[0] for ln in axq.get_lines() if ln.get_gid() == "robot_limit")
        assert robot == pytest.approx([lo[j], hi[j]])
    assert fig.axes[-1].get_xlabel() == "time [s]"
    r = _excite(tmp_path / "none", "--rate", "50", "--no-plot")
    assert r.exit_code == 0 and not list((tmp_path / "none").glob("*.png"))
