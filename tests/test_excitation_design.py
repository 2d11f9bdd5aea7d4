"""Excitation design: the optimised trajectory is ≥ 5× better conditioned than random Fourier
trajectories under the same limits, and respects every limit (checked independently)."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.cli import excite as _excite  # noqa: F401  (registers `sensorless excite`)
from sensorless.data import read_trajectory
from sensorless.errors import ExcitationError
from sensorless.excitation import (
    CartesianBox,
    ExcitationLimits,
    FourierTrajectory,
    design_excitation,
    excitation_metrics,
    random_excitation,
    random_fourier,
)
from sensorless.excitation.problem import FourierProblem
from sensorless.identification import base_parameters
from sensorless.regressor import ModelStructure

BOX = CartesianBox("tool0", lower=(-np.inf, -np.inf, -0.2))  # tool flange above z = −0.2 m


@pytest.fixture(scope="module")
def structure(ur5):
    return ModelStructure(ur5)


@pytest.fixture(scope="module")
def design(structure):
    return design_excitation(structure, harmonics=4, base_freq=0.2, n_samples=100, maxiter=40, seed=0, cartesian=[BOX], start_at_rest=True)


def test_random_excitation_is_random_fourier_under_the_same_limits(ur5):
    limits = ExcitationLimits.from_robot(ur5)
    a = random_excitation(limits, harmonics=4, base_freq=0.2, rng=3)
    b = random_fourier(ur5, harmonics=4, base_freq=0.2, rng=3)
    assert np.allclose(a.a, b.a) and np.allclose(a.b, b.b) and np.allclose(a.q0, b.q0)


def test_optimised_condition_number_is_at_least_5x_lower_than_random(design, structure):
    # recompute the figures independently on a dense grid, with the structure's own (sign) Coulomb terms
    ind = base_parameters(structure).independent
    grid = np.arange(400) / (400 * 0.2)
    opt = excitation_metrics(structure, *design.trajectory.evaluate(grid), independent=ind)["cond"]
    limits = design.limits
    rand = [
        excitation_metrics(structure, *random_excitation(limits, harmonics=4, base_freq=0.2, rng=k).evaluate(grid), independent=ind)["cond"]
        for k in range(5)
    ]
    assert opt * 5 <= rand[0], (opt, rand[0])  # same seed as the optimiser's start
    assert opt * 5 <= np.median(rand), (opt, rand)
    assert design.improvement >= 5 and design.improvement_median >= 5
    assert design.metrics["cond"] == pytest.approx(opt, rel=0.1)


def test_every_limit_holds_on_a_dense_grid(design):
    L = design.limits
    t = np.linspace(0, design.trajectory.period, 20001)
    q, v, a = design.trajectory.evaluate(t)
    assert np.all(q >= L.lower - 1e-12) and np.all(q <= L.upper + 1e-12)
    assert np.all(np.abs(v) <= L.velocity + 1e-12)
    assert np.all(np.abs(a) <= L.acceleration + 1e-12)
    dq, dv, da = design.trajectory.bounds()  # the analytic worst case holds too
    assert np.all(design.trajectory.q0 - dq >= L.lower - 1e-9) and np.all(design.trajectory.q0 + dq <= L.upper + 1e-9)
    assert np.all(dv <= L.velocity + 1e-9) and np.all(da <= L.acceleration + 1e-9)
    assert max(design.limit_violation.values()) <= 0
    # starts at rest
    _, v0, a0 = design.trajectory.evaluate(np.array([0.0]))
    assert np.allclose(v0, 0, atol=1e-8) and np.allclose(a0, 0, atol=1e-8)


def test_cartesian_box_holds_on_the_samples(design, ur5):
    m, d = ur5.model, ur5.model.createData()
    fid = ur5.frame_id("tool0")
    t = np.arange(100) / (100 * 0.2)
    q, _, _ = design.trajectory.evaluate(t)
    z = []
    for qi in ur5.full_configuration(q):
        pin.framesForwardKinematics(m, d, qi)
        z.append(d.oMf[fid].translation[2])
    assert min(z) >= -0.2 - 1e-6
    assert design.cartesian_violation <= 1e-6


def test_save_exports_parameters_and_samples(design, tmp_path):
    js, npz = design.save(tmp_path, rate=50.0, periods=2.0)
    doc = json.loads(js.read_text())
    traj = FourierTrajectory(doc["trajectory"]["base_freq"], np.array(doc["trajectory"]["a"]), np.array(doc["trajectory"]["b"]),
                             np.array(doc["trajectory"]["q0"]), tuple(doc["trajectory"]["joint_names"]))
    logged = read_trajectory(npz)
    assert len(logged) == int(2 * design.trajectory.period * 50)
    assert np.allclose(logged.q, traj.evaluate(logged.t)[0])
    assert doc["limits"]["joint_names"] == list(design.limits.joint_names)
    assert doc["criterion"] == "cond" and doc["criterion_value"] == pytest.approx(design.metrics["cond"])
    assert doc["random_baseline"]["metrics"]["cond"] > doc["criterion_value"]


def test_gradient_matches_central_differences(structure, ur5):
    limits = ExcitationLimits.from_robot(ur5)
    for crit in ("cond", "dopt"):
        prob = FourierProblem(structure, limits, 2, 0.2, 40, crit, (), 0.05)
        x = prob.pack(random_excitation(limits, harmonics=2, base_freq=0.2, rng=1, fill=0.9))
        _, g = prob.value_and_grad(x, h=1e-7)
        d = np.random.default_rng(0).normal(size=x.size)
        fd = (prob.value(x + 1e-6 * d) - prob.value(x - 1e-6 * d)) / 2e-6
        assert g @ d == pytest.approx(fd, rel=1e-4, abs=1e-6)


def test_d_optimality_improves_information(structure):
    d = design_excitation(structure, harmonics=2, base_freq=0.2, n_samples=60, maxiter=15, criterion="dopt", seed=1, n_random=1)
    assert d.metrics["neg_logdet"] < d.random_metrics["neg_logdet"]
    assert max(d.limit_violation.values()) <= 0


def test_bad_inputs_raise_typed_errors(structure, ur5):
    with pytest.raises(ExcitationError, match="criterion"):
        design_excitation(structure, criterion="aopt")
    limits = ExcitationLimits.from_robot(ur5)
    other = ExcitationLimits(tuple(f"j{k}" for k in range(6)), limits.lower, limits.upper, limits.velocity, limits.acceleration)
    with pytest.raises(ExcitationError, match="joints"):
        design_excitation(structure, other, maxiter=1)
    with pytest.raises(ExcitationError, match="lower >= upper"):
        ExcitationLimits(limits.joint_names, limits.upper, limits.lower, limits.velocity, limits.acceleration)


def test_cli_excite_writes_json_and_npz(tmp_path):
    out = tmp_path / "ex"
    res = CliRunner().invoke(app, ["excite", "--robot", "ur5", "--harmonics", "2", "--base-freq", "0.2", "--n-samples", "40",
                                   "--maxiter", "5", "--rate", "20", "--out", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "excitation.json").read_text())
    assert doc["settings"]["harmonics"] == 2 and doc["export"]["rate_hz"] == 20.0
    assert len(read_trajectory(out / "trajectory.npz")) == 100
    bad = CliRunner().invoke(app, ["excite", "--robot", "ur5", "--criterion", "x", "--out", str(tmp_path / "bad")])
    assert bad.exit_code == 2 and "criterion" in bad.output and not (tmp_path / "bad").exists()
