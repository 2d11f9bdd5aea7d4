"""model.urdf's prior masses: the greedy over bodies run by bisection makes the same choices and the
same final call as the plain greedy, with O(log n) calls per rejected body (issue 28: TALOS 35 → 8 SDPs);
``identify --method ols`` chooses model.urdf's values without importing cvxpy (issue 28; the SDP itself
against cvxpy: test_identification_prior_projection.py)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from sensorless.data import write_npz
from sensorless.excitation import random_fourier
from sensorless.identification.urdf_values import greedy_prefixes
from sensorless.testing import perturbed_truth, synthetic_trajectory


def _naive(order, reach):
    kept, cand = [], None
    for k in order:
        trial = reach(kept + [k])
        if trial is not None:
            kept, cand = kept + [k], trial
    return kept, cand


@pytest.mark.parametrize("seed", range(30))
def test_bisection_greedy_is_the_plain_greedy(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 40))
    order = list(rng.permutation(n))
    # a monotone oracle: a set of bodies is reachable iff it holds at most `cap` of the "hard" ones
    hard = set(rng.choice(n, size=int(rng.integers(0, n + 1)), replace=False).tolist()) if n else set()
    cap = int(rng.integers(0, 4))
    calls: list[tuple] = []

    def oracle(ks):
        return np.array(ks, dtype=float) if sum(k in hard for k in ks) <= cap else None

    def reach(ks):
        calls.append(tuple(ks))
        return oracle(ks)

    kept, cand = greedy_prefixes(order, reach)
    kept0, cand0 = _naive(order, oracle)
    assert kept == kept0
    assert (cand is None and cand0 is None) or np.array_equal(cand, cand0)
    # few calls, and the result comes from a call on exactly the final list (as the greedy's last success)
    rejected = len(order) - len(kept)
    assert len(calls) <= 1 + rejected * (2 * np.log2(max(n, 2)) + 3)
    if kept:
        assert tuple(kept) in calls


def test_ols_identify_writes_prior_masses_without_cvxpy(ur5, tmp_path):
    truth = perturbed_truth(ur5, rng=0)
    write_npz(synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(100, 10.0), noise_std=0.05, rng=2),
              tmp_path / "log.npz")
    out = tmp_path / "out"
    code = ("import sys\nfrom sensorless.cli import app\ntry:\n    app(sys.argv[1:])\nexcept SystemExit as e:\n"
            "    assert not e.code, e.code\nprint('cvxpy' in sys.modules)")
    args = ["identify", "--robot", "ur5", "--data", tmp_path / "log.npz", "--method", "ols", "--no-plot", "--out", out]
    run = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip().splitlines()[-1] == "False", run.stdout
    values = json.loads((out / "result.json").read_text())["urdf_values"]
    # a fixed-base arm's masses are not in its torques: the prior-mass SDPs ran
    assert values["prior_mass_bodies"] or values.get("undetermined_mass_bodies")
    assert (out / "model.urdf").is_file()


def test_an_unconstrained_fit_no_physical_bodies_reproduce_costs_one_program(ur5, monkeypatch):
    """An OLS fit on a short noisy log whose identified dynamics no physical bodies give: every prior
    mass is unreachable (fixing masses only adds constraints), found with one SDP instead of the
    greedy's 18 (issue 28: ~0.08 s of `--method ols` after its figures are sent); model.urdf gets the
    regularised values, each body listed as undetermined."""
    import warnings

    import sensorless.identification.prior_projection as projection
    from sensorless.identification import identify
    from sensorless.identification.urdf_values import urdf_inertials
    from sensorless.parameters import check_physical_consistency

    truth = perturbed_truth(ur5, rng=0)
    traj = synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(60, 6.0), noise_std=0.05, rng=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the short log's poorly identified parameters
        res = identify(ur5, traj, method="ols")
    shown = res.diagnostics.pop("presented")  # the path of a result without a presented model (an older result.json)
    assert all(r.consistent for r in check_physical_consistency(res.inertial_parameters))  # what is presented: physical
    res.parameters = np.array(shown["fit_parameters"])  # the OLS fit itself
    assert not all(r.consistent for r in check_physical_consistency(res.inertial_parameters))
    calls = []
    solve = projection.solve_prior_projection
    monkeypatch.setattr(projection, "solve_prior_projection", lambda *a, **k: calls.append(1) or solve(*a, **k))
    pi, info = urdf_inertials(res)
    assert len(calls) == 1
    assert info["values"] == "regularised" and not info["prior_mass_bodies"]
    assert info["undetermined_mass_bodies"] == list(ur5.joint_names)
    np.testing.assert_array_equal(pi, res.inertial_parameters)
