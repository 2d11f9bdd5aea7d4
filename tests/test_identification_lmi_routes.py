"""The LMI program's two routes to the solver: Clarabel's own API (conic rows from the builders, the
regulariser's metric) and cvxpy (the same program as expressions, the oracle). Same constraints,
same solutions, the same γ chosen on real logs, and no cvxpy import on the default path."""

from __future__ import annotations


import numpy as np
import pytest
from conftest import KUKA, REALDATA, identify_imports, realdata

from sensorless.identification.constraints import (
    BodyMassBounds,
    ComInEllipsoid,
    DensityRealizable,
    NonNegativeArmature,
    NonNegativeFriction,
    PseudoInertiaPSD,
    TotalMass,
    default_constraints,
)
from sensorless.identification.lmi import LmiProblem, build_lmi
from sensorless.identification.prior_projection import svec
from sensorless.regressor import ModelStructure, compress
from sensorless.testing import perturbed_truth, synthetic_trajectory

WPI = REALDATA / "dvrk_psm_wpi" / "data" / "psm" / "measured_trajectory"


@pytest.fixture(scope="module")
def case(panda):
    from sensorless.excitation import random_fourier

    s = ModelStructure(panda)
    truth = perturbed_truth(panda, rng=0)
    motion = random_fourier(panda, rng=1, base_freq=0.2).sample(100.0, 5.0)
    clean = synthetic_trajectory(truth, motion)
    train = synthetic_trajectory(truth, motion, noise_std=0.03 * np.sqrt((clean.tau**2).mean(0)), rng=2)
    test = synthetic_trajectory(truth, random_fourier(panda, rng=3, base_freq=0.2).sample(100.0, 5.0))
    return s, compress(s, train), test


_UNITS = np.array([np.eye(4)[[i]].T @ np.eye(4)[[j]] + (np.eye(4)[[j]].T @ np.eye(4)[[i]] if i != j else 0)
                   for j in range(4) for i in range(j + 1)])  # symmetric unit matrices


def _smat(s: np.ndarray) -> np.ndarray:
    """The symmetric matrix whose Clarabel packing (svec) is ``s``."""
    return np.einsum("m,mab->ab", np.linalg.solve(svec(_UNITS).T, s), _UNITS)


def _conic_margin(rows, x: np.ndarray) -> float:
    """Smallest margin of ``s = b − A x`` in its cones (< 0: violated)."""
    out = []
    for r in rows:
        s = r.b - r.A @ x
        out.append({"zero": lambda: -np.abs(s).max(), "nonneg": lambda: s.min(),
                    "soc": lambda: s[0] - np.linalg.norm(s[1:]),
                    "psd": lambda: np.linalg.eigvalsh(_smat(s))[0]}[r.kind]())
    return min(out, default=np.inf)


def _cvxpy_margin(cons) -> float:
    import cvxpy as cp

    out = []
    for c in cons:
        if isinstance(c, cp.constraints.PSD):
            out.append(np.linalg.eigvalsh(c.expr.value)[0])
        elif isinstance(c, cp.constraints.Equality):
            out.append(-np.abs(c.expr.value).max())
        else:  # lhs <= rhs
            out.append(np.min(np.asarray(c.args[1].value) - np.asarray(c.args[0].value)))
    return min(out, default=np.inf)


@pytest.mark.parametrize("builder", [
    PseudoInertiaPSD(), PseudoInertiaPSD(eps=1e-6), DensityRealizable(), ComInEllipsoid(), NonNegativeFriction(),
    NonNegativeArmature(), BodyMassBounds(lower=0.2, upper={"panda_joint3": 2.5}), TotalMass(value=17.0),
    TotalMass(lower=16.0, upper=19.0)], ids=lambda b: f"{b.name}")
def test_conic_rows_are_the_cvxpy_constraints(case, builder, rng):
    """At the prior and at random points around it, the conic rows' smallest margin equals the cvxpy
    constraints' (the same numbers: eigenvalue, distance, slack), so both routes solve one program."""
    import cvxpy as cp

    s, ne, _ = case
    ctx = build_lmi(ne, s).ctx
    x = cp.Variable(s.n_params)
    cons = builder(x, ctx)
    rows = builder.conic(ctx)
    assert rows and all(r.A.shape == (len(r.b), s.n_params) for r in rows)
    signs = set()
    for k in range(12):
        v = ctx.x0 if k == 0 else ctx.x0 * (1 + 0.6 * rng.standard_normal(s.n_params)) + 0.2 * rng.standard_normal(s.n_params)
        x.value = v
        a, b = _conic_margin(rows, v), _cvxpy_margin(cons)
        assert a == pytest.approx(b, rel=1e-9, abs=1e-12), (k, a, b)
        signs.add(a >= 0)
    if not isinstance(builder, TotalMass) or builder.value is None:
        assert signs == {True, False}  # the points test both sides of the constraint


KINDS = {"default": {}, "euclidean": {"regularization": "euclidean"}, "none": {"regularization": None},
         "com_bounds_total": {"constraints": [*default_constraints(), ComInEllipsoid(), BodyMassBounds(lower=0.3),
                                              TotalMass(lower=15.0, upper=20.0)]}}


@pytest.mark.parametrize("kind", list(KINDS))
def test_the_quadratic_objective_is_the_cvxpy_objective(case, kind, rng):
    """``½ xᵀPx + qᵀx + const`` equals cvxpy's objective at any point and γ (with the constraint test
    above: both routes hand the solver one program)."""
    s, ne, _ = case
    prob = build_lmi(ne, s, **KINDS[kind])
    R, z = prob.data_factor
    G = prob._conic["G"]
    for g in (0.0, 1e-6, 1e-3, 1.0):
        P, q = prob.quadratic_objective(g)
        const = z @ z + g / prob.n_samples * prob.ctx.x0 @ G @ prob.ctx.x0
        prob.gamma.value = g / prob.n_samples
        for _ in range(3):
            x = prob.ctx.x0 * (1 + 0.3 * rng.standard_normal(s.n_params)) + 0.1 * rng.standard_normal(s.n_params)
            prob.x.value = x
            assert 0.5 * x @ P @ x + q @ x + const == pytest.approx(prob.problem.objective.value, rel=1e-10)


@pytest.mark.parametrize("kind", list(KINDS))
def test_both_routes_give_the_same_solution(case, kind):
    """Solved both ways at the default tolerance: the same objective to the solvers' gap and the same
    predicted torques on another trajectory to 1e-3 (RMS; ~2e-4 seen). Directions the data barely
    see are held only by the weak prior and move by as much as a 1e-8 gap allows."""
    s, ne, test = case
    prob = build_lmi(ne, s, **KINDS[kind])
    for g in ((0.0,) if kind == "none" else (1e-6, 1e-3, 1.0)):
        direct = prob.solve(g)
        keep, prob._conic = prob._conic, None
        try:
            via_cvxpy = prob.solve(g)
        finally:
            prob._conic = keep
        assert (direct.settings["route"], via_cvxpy.settings["route"]) == ("clarabel", "cvxpy")
        assert direct.solver == via_cvxpy.solver == "CLARABEL" and direct.consistent and via_cvxpy.consistent
        assert direct.objective == pytest.approx(via_cvxpy.objective, rel=2e-4)
        a, b = s.torques(direct.params, test), s.torques(via_cvxpy.params, test)
        assert np.sqrt(np.mean((a - b) ** 2)) <= 1e-3 * np.sqrt(np.mean(b**2))


def test_what_has_no_conic_rows_goes_through_cvxpy(case):
    s, ne, _ = case

    class OnlyCvxpy:  # a user-written builder: cvxpy constraints only
        name, hint = "link1_light", "drop it"

        def __call__(self, x, ctx):
            return [x[10] <= 3.0 / ctx.body_mass[1]]

    for kw in ({"regularization": "entropic"}, {"constraints": [*default_constraints(), OnlyCvxpy()]}):
        sol = build_lmi(ne, s, **kw).solve(1e-3)
        assert sol.settings["route"] == "cvxpy" and sol.status == "optimal" and sol.consistent
    assert sol.params[10] <= 3.0 + 1e-6


def test_default_identify_does_not_import_cvxpy(ur5, tmp_path):
    """`sensorless identify` with the defaults (LMI, γ by cross-validation) never imports cvxpy
    (~0.55 s of imports) and records the route in result.json."""
    import json

    out, imported = identify_imports(ur5, tmp_path, [], ["cvxpy"])
    assert imported == {"cvxpy": False}
    d = json.loads((out / "result.json").read_text())["diagnostics"]
    assert d["lmi"]["settings"]["route"] == "clarabel" and d["gamma_selection"]["gamma"] == d["gamma"]


def _gamma_both_routes(monkeypatch, tmp_path, **options):
    from sensorless.run import RunConfig, identify_run

    chosen = []
    for route in ("clarabel", "cvxpy"):
        with monkeypatch.context() as m:
            if route == "cvxpy":
                m.setattr(LmiProblem, "_conic_program", lambda self: None)
            run = identify_run(RunConfig.from_options(**options, out=str(tmp_path / route), plot=False))
        d = run.result.diagnostics
        assert d["lmi"]["settings"]["route"] == route
        chosen.append(d["gamma"])
    return chosen


def test_kuka_gamma_is_the_same_on_both_routes(monkeypatch, tmp_path):
    k = realdata(KUKA)
    a, b = _gamma_both_routes(monkeypatch, tmp_path, robot=str(k / "model/kuka_lwr4.urdf"),
                              data=[str(k / "data/KUKA/HW/measurements_1.npz")],
                              validate=[str(k / "data/KUKA/HW/measurements_3.npz")], joint_terms="fv,fc,offset")
    assert a == b


def test_dvrk_wpi_gamma_is_the_same_on_both_routes(monkeypatch, tmp_path):
    w = realdata(WPI)
    a, b = _gamma_both_routes(monkeypatch, tmp_path, robot="dvrk_psm", data=[str(w / "one_results.csv")],
                              validate=[str(w / "two_results.csv")], columns="q=0:7;v=7:14;tau=14:21", rate=200,
                              lowpass=5.4, coulomb_smoothing=0.2)
    assert a == b


def test_non_finite_program_data_is_a_solver_error_not_a_panic(case):
    from sensorless.errors import SolverError

    s, ne, _ = case
    prob = build_lmi(ne, s)
    prob._conic["Rtz"] = np.full_like(prob._conic["Rtz"], np.nan)
    with pytest.raises(SolverError, match="CLARABEL: error: non-finite data"):
        prob.solve(1e-3, solver="CLARABEL")
