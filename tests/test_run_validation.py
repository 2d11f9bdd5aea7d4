"""sensorless.run.validation: the OLS baseline is an ordinary OLS fit on the same logs, the held-out
table scores each model on each held-out log, and an implausible model is refused unless accepted."""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest

from sensorless.data import write_npz
from sensorless.errors import PlausibilityError
from sensorless.excitation import random_fourier
from sensorless.regressor import ModelStructure
from sensorless.run import RunConfig, identify_run
from sensorless.run.backend import Fit
from sensorless.run.validation import check_plausible, floating_base_report, held_out_scores, ols_baseline
from sensorless.testing import perturbed_truth, synthetic_trajectory
from sensorless.torque_models import PhysicalModel

TERMS, EPS = "fv,fc,offset", 0.02


@pytest.fixture(scope="module")
def run(tmp_path_factory, ur5):
    """An LMI run (fixed γ, fixed friction law) on a 4 s UR5 log, with a held-out 3 s log."""
    d = tmp_path_factory.mktemp("validation")
    truth = perturbed_truth(ur5, rng=5)
    for name, seed, T in (("train", 11, 4.0), ("test", 13, 3.0)):
        traj = synthetic_trajectory(truth, random_fourier(ur5, rng=seed).sample(100, T), noise_std=0.05, rng=seed + 1)
        write_npz(traj, d / f"{name}.npz")
    return identify_run(RunConfig.from_options(robot="ur5", data=[d / "train.npz"], validate=[d / "test.npz"],
                                               joint_terms=TERMS, coulomb_smoothing=EPS, gamma=1e-3, weights="none",
                                               plot=False))


def test_baseline_is_an_independent_ols_fit(run, ur5):
    ols = PhysicalModel(structure=ModelStructure(ur5, joint_terms=TERMS.split(","), coulomb_smoothing=EPS),
                        method="ols", outliers="keep", weights=None, check_torques=False).fit(run.train)
    fit = np.array(ols.result_.diagnostics["presented"].get("fit_parameters", ols.parameters_))  # the OLS solution
    assert np.allclose(run.baseline.parameters_, fit, rtol=1e-10, atol=1e-10 * np.abs(fit).max())
    # called directly on the run's own compressed equations, the same
    direct = ols_baseline(Fit(run.result, run.structure, run.model, run.train, [], equations=run.result.equations), None)
    assert np.array_equal(direct.parameters_, run.baseline.parameters_)
    # and not the constrained fit
    assert not np.allclose(run.model.parameters_, fit)


def test_held_out_scores_each_model_on_each_log(run):
    paths = run.config.logs.validate
    doc, tables = held_out_scores(paths, run.val, "lmi", run.model, run.cad, run.baseline)
    v = doc[str(paths[0])]
    assert set(v) == {"lmi", "cad", "ols"} and v == run.doc["validation"][str(paths[0])]
    assert v["lmi"] == run.model.score(run.val[0]).to_dict() and v["cad"] == run.cad.score(run.val[0]).to_dict()
    assert v["lmi"]["mean_nrmse"] < v["cad"]["mean_nrmse"]  # the fit predicts the other motion better than the prior
    assert [t for t, _ in tables] == [f"held-out {paths[0].name}"] and list(tables[0][1]) == ["CAD", "OLS", "LMI"]
    doc, tables = held_out_scores(paths, run.val, "lmi", run.model, run.cad, None)  # no baseline: no OLS row
    assert set(doc[str(paths[0])]) == {"lmi", "cad"} and list(tables[0][1]) == ["CAD", "LMI"]


def test_an_implausible_model_is_refused_unless_accepted(run, ur5):
    check_plausible(run.result, {}, accept=False)  # the fit itself is plausible
    assert "implausible_accepted" not in run.result.diagnostics
    bad = copy.deepcopy(run.result)
    k = 2
    body = ur5.body_names[k]
    bad.parameters = np.array(bad.parameters, dtype=float)
    bad.parameters[10 * k: 10 * k + 10] *= 1000  # a body 1000× heavier (the same CoM)
    with pytest.raises(PlausibilityError, match=body):
        check_plausible(bad, {}, accept=False, urdf_values="regularised")
    with pytest.warns(UserWarning, match=r"`solver\.accept_implausible`.*" + body):
        check_plausible(bad, {}, accept=True, urdf_values="regularised")
    assert any(body in p for p in bad.diagnostics["implausible_accepted"])


def test_no_floating_base_report_without_measured_wrenches(run):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert floating_base_report(run.structure, run.result, run.train, run.val, run.config.logs.validate) is None
