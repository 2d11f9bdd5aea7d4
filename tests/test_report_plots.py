"""Figures (issue 24, item 6): units on every axis, one legend above the data, a residual panel
per row, each model's trace distinguishable, one figure per limb for a robot with several, and the
`identify` figures (torques.png, friction.png) from a run on a small simulated log.

The figures are inspected as matplotlib objects (labels, artists, their data), never as pixels.
The monitor, estimate-force and excite figures are tested next to those commands' tests
(test_estimation_collision.py, test_estimation_force.py, test_excitation_limits.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.robot import Robot, load_robot

LEGS = {"FL": ["FL_HAA", "FL_HFE", "FL_KFE"], "FR": ["FR_HAA", "FR_HFE", "FR_KFE"],
        "HL": ["HL_HAA", "HL_HFE", "HL_KFE"], "HR": ["HR_HAA", "HR_HFE", "HR_KFE"]}
BASE = ["base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz"]


def _tree(parents: dict[str, str | None], prismatic=()) -> Robot:
    """A robot from {joint: parent joint (None: the fixed base)}, in insertion order."""
    m = pin.Model()
    ids = {None: 0}
    rng = np.random.default_rng(0)
    for name, parent in parents.items():
        jm = pin.JointModelPZ() if name in prismatic else pin.JointModelRY()
        ids[name] = m.addJoint(ids[parent], jm, pin.SE3(np.eye(3), rng.normal(size=3) * 0.2), name)
        m.appendBodyToJoint(ids[name], pin.Inertia.Random(), pin.SE3.Identity())
    m.lowerPositionLimit, m.upperPositionLimit = -np.ones(m.nq), np.ones(m.nq)
    m.velocityLimit, m.effortLimit = 2.0 * np.ones(m.nv), 50.0 * np.ones(m.nv)
    return Robot(m, name="tree")


def _recorder(monkeypatch, *modules):
    """Patch ``save_figure`` in ``modules``: every figure saved is kept as {file name: figure}."""
    from sensorless.report.figure_kit import save_figure

    saved = {}

    def rec(fig, path):
        saved[path.name] = fig
        return save_figure(fig, path)

    for m in modules:
        monkeypatch.setattr(m, "save_figure", rec)
    return saved


def _pairs(fig):
    """(signal, residual) axes pairs of a torque or friction figure (the residual axis is the one below)."""
    axes = fig.axes
    return list(zip(axes[0::2], axes[1::2]))


# ---- rows: limbs and units ----------------------------------------------------------------------
def test_solo12_is_grouped_into_its_base_and_four_legs():
    from sensorless.regressor import ModelStructure
    from sensorless.report import limb_groups

    solo = load_robot("solo12")
    rows = ModelStructure(solo).row_names
    assert len(rows) == 18
    groups = limb_groups(solo, rows)
    assert groups == {"base": BASE, **LEGS}
    assert limb_groups(solo, list(solo.joint_names)) == LEGS  # actuated rows only: no base group


def test_one_limb_is_one_group_several_are_split_and_a_long_tree_is_split_at_its_branch():
    from sensorless.report import limb_groups

    panda = load_robot("panda")  # one chain from the base (the fingers hang under the hand): one figure
    assert limb_groups(panda, panda.joint_names) == {"": list(panda.joint_names)}
    arms = _tree({"left_1": None, "left_2": "left_1", "right_1": None, "right_2": "right_1"})
    assert limb_groups(arms, arms.joint_names) == {"left": ["left_1", "left_2"], "right": ["right_1", "right_2"]}
    torso = _tree({"t1": None, "t2": "t1", "la1": "t2", "la2": "la1", "ra1": "t2", "ra2": "ra1"})
    assert limb_groups(torso, torso.joint_names) == {"": list(torso.joint_names)}  # 6 rows: readable as one
    assert limb_groups(torso, torso.joint_names, max_rows=4) == {"t": ["t1", "t2"], "la": ["la1", "la2"],
                                                                 "ra": ["ra1", "ra2"]}
    named = _tree({"arm_1": None, "arm_2": "arm_1", "gripper": "arm_2", "leg_1": None, "leg_2": "leg_1"})
    assert limb_groups(named, named.joint_names) == {"arm": ["arm_1", "arm_2", "gripper"], "leg": ["leg_1", "leg_2"]}
    assert limb_groups(None, ["a", "b"]) == {"": ["a", "b"]}  # no robot (a friction bench)


def test_units_per_row():
    from sensorless.report.rows import effort_unit, motion_units

    r = _tree({"rev": None, "lin": "rev"}, prismatic={"lin"})
    assert [effort_unit(r, j) for j in ("rev", "lin", "base_vz", "base_wx")] == ["N·m", "N", "N", "N·m"]
    assert motion_units(r, "lin") == ("m", "m/s", "m/s²") and motion_units(r, "rev") == ("rad", "rad/s", "rad/s²")
    assert effort_unit(None, "slide") == "N·m or N"


# ---- torque figure ------------------------------------------------------------------------------
def _signals(n=600, rows=2, seed=0):
    rng = np.random.default_rng(seed)
    t = 100.0 + np.arange(n) * 0.01
    meas = np.sin(np.outer(t, np.arange(1, rows + 1))) + 0.05 * rng.normal(size=(n, rows))
    preds = {"LMI": meas + 0.02, "OLS": meas + 0.021, "CAD": 0.8 * meas}  # OLS ≈ LMI: the case that hid one
    return t, meas, preds


def test_torque_figure_has_units_a_residual_per_row_distinct_traces_and_a_legend_above_the_data():
    from sensorless.report import torque_figure

    r = _tree({"rev": None, "lin": "rev"}, prismatic={"lin"})
    t, meas, preds = _signals()
    fig = torque_figure(t, meas, preds, ["rev", "lin"], robot=r, title="t")
    pairs = _pairs(fig)
    assert len(pairs) == 2
    for (ax, res), u, q in zip(pairs, ["N·m", "N"], ["torque", "force"]):
        assert ax.get_ylabel() == f"{q} [{u}]" and res.get_ylabel() == f"residual [{u}]"
        assert u in ax.get_title(loc="left")  # the RMSE per model, in the row's unit
        lines = {ln.get_label(): ln for ln in ax.get_lines()}
        styles = {(ln.get_color(), ln.get_linestyle()) for k, ln in lines.items() if k != "measured"}
        assert len(styles) == 3  # each model its own colour and line style
        z = [lines[k].get_zorder() for k in ("measured", "LMI", "OLS", "CAD")]
        assert z == sorted(z) and len(set(z)) == 4  # measured under every model, each model over the previous
        for name, p in preds.items():  # the residual panel draws measured − prediction
            line = next(ln for ln in res.get_lines() if ln.get_label() == name)
            j = ["rev", "lin"].index(ax.get_title(loc="left").split()[0])
            np.testing.assert_allclose(line.get_ydata(), meas[:, j] - p[:, j])
    assert pairs[-1][1].get_xlabel() == "time [s]" and pairs[0][1].get_xlim()[0] < 1.0  # time from the first sample
    (legend,) = fig.legends
    assert [x.get_text() for x in legend.get_texts()] == ["measured", "LMI", "OLS", "CAD"]
    fig.canvas.draw()
    top_of_axes = max(a.get_window_extent().y1 for a in fig.axes)
    assert legend.get_window_extent().y0 >= top_of_axes  # above every axis: it covers no data


def test_torques_per_limb_for_solo12(tmp_path):
    from sensorless.report import plot_torques_by_limb

    solo = load_robot("solo12")
    rows = BASE + [j for leg in LEGS.values() for j in leg]
    t, meas, preds = _signals(rows=18)
    figs = plot_torques_by_limb(t, meas, preds, rows, tmp_path, robot=solo, title="solo12")
    assert sorted(p.name for p in figs) == sorted(p.name for p in tmp_path.iterdir()) == sorted(
        f"torques_{g}.png" for g in ["base", *LEGS])
    by_name = {p.name: f for p, f in figs.items()}
    fl = _pairs(by_name["torques_FL.png"])
    assert [a.get_title(loc="left").split()[0] for a, _ in fl] == LEGS["FL"]
    base = _pairs(by_name["torques_base.png"])
    assert [a.get_ylabel() for a, _ in base] == ["force [N]"] * 3 + ["torque [N·m]"] * 3
    assert by_name["torques_FL.png"].get_suptitle() == "solo12: FL"


# ---- identify: torques.png and friction.png from a run ---------------------------------------
def test_identify_writes_torques_with_residuals_of_every_model_and_friction_with_units(ur5, tmp_path, monkeypatch):
    import sensorless.report.friction_plot as fp
    import sensorless.report.plots as tp
    from sensorless.data import write_npz
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    truth = perturbed_truth(ur5, rng=0)
    for name, seed in (("train", 1), ("test", 3)):
        log = synthetic_trajectory(truth, random_fourier(ur5, rng=seed).sample(100, 6.0), noise_std=0.1, rng=seed + 1)
        write_npz(log, tmp_path / f"{name}.npz")
    saved = _recorder(monkeypatch, tp, fp)
    # drawn in this process (not the figure process), to read the figures back; the figure process writes
    # the same bytes (tests/test_cli_identify_e2e.py)
    monkeypatch.setattr("sensorless.cli.identify._start_plotter", lambda: None)
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / "train.npz"), "--validate",
                                 str(tmp_path / "test.npz"), "--joint-terms", "fv,fc,offset", "--method", "wls", "--out",
                                 str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "m" / "torques.png").stat().st_size > 10_000 and set(saved) == {"torques.png", "friction.png"}
    fig = saved["torques.png"]
    assert [x.get_text() for x in fig.legends[0].get_texts()] == ["measured", "WLS", "OLS", "CAD"]
    pairs = _pairs(fig)
    assert [a.get_title(loc="left").split()[0] for a, _ in pairs] == list(ur5.joint_names)
    assert all(a.get_ylabel() == "torque [N·m]" and b.get_ylabel() == "residual [N·m]" for a, b in pairs)
    assert "held-out" in fig.get_suptitle()
    fr = saved["friction.png"]
    fpairs = _pairs(fr)
    assert len(fpairs) == 6
    for a, b in fpairs:
        assert a.get_ylabel() == "friction [N·m]" and b.get_ylabel() == "residual [N·m]" and b.get_xlabel() == "v [rad/s]"
        dots = b.get_lines()[1].get_ydata()  # [0] is the zero line
        assert 0.05 < np.std(dots) < 0.2  # what the identified friction leaves: the torque noise (σ = 0.1 N·m)
    assert len(fr.legends) == 1 and all(a.get_legend() is None for a in fr.axes)
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / "train.npz"), "--joint-terms",
                                 "fv,fc,offset", "--method", "ols", "--no-plot", "--out", str(tmp_path / "n")])
    assert r.exit_code == 0, r.output
    assert not list((tmp_path / "n").glob("*.png"))  # --no-plot: no torques.png, no friction.png


def test_long_logs_are_decimated_keeping_short_peaks():
    """An hour at 1 kHz drawn in ~4000 points: a one-sample spike (a contact, a glitch) is still drawn."""
    from sensorless.report.figure_kit import envelope_indices

    rng = np.random.default_rng(1)
    y = rng.normal(size=(3_600_000, 2))
    y[1_234_567, 1] = 50.0
    y[:10, 0] = np.nan  # an observer's warm-up
    idx = envelope_indices(y, 4000)
    assert len(idx) <= 4002 and 1_234_567 in idx and idx[0] == 0 and idx[-1] == len(y) - 1
    assert np.all(np.diff(idx) > 0)


@pytest.mark.parametrize("seed", range(4))
def test_in_view_locator_draws_the_ticks_of_maxnlocator_and_builds_no_other(seed):
    """The panels' locator gives MaxNLocator's locations inside the view, and only those: the ticks
    drawn, their labels and the PNG are the same, with no tick artists built for locations off the axis."""
    import io

    from matplotlib.ticker import MaxNLocator

    from sensorless.report.figure_kit import in_view_locator, new_figure

    rng = np.random.default_rng(seed)
    pngs, built = [], []
    for make in (MaxNLocator, in_view_locator):
        fig = new_figure(3.0, 2.0)
        ax = fig.add_subplot()
        lo = rng.normal() * 10.0 ** rng.integers(-3, 4)
        ax.plot([lo, lo + abs(rng.normal()) * 10.0 ** rng.integers(-3, 4)], [0.0, 1.0])
        ax.xaxis.set_major_locator(make(nbins=6))
        buf = io.BytesIO()
        fig.savefig(buf, format="png")
        pngs.append(buf.getvalue())
        view = sorted(ax.get_xlim())
        locs = ax.xaxis.get_majorticklocs()
        built.append((len(ax.xaxis.majorTicks), [x for x in locs if view[0] <= x <= view[1]], len(locs)))
        rng = np.random.default_rng(seed)  # the same line for both locators
    (n_all, drawn_all, _), (n_view, drawn_view, locs_view) = built
    assert drawn_view == drawn_all and locs_view == len(drawn_view)
    assert n_view == len(drawn_view) < n_all
    assert pngs[0] == pngs[1]
