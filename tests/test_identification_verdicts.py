"""Issue 23 items 1-3: verdicts on physical quantities, a γ that cannot run away, plausibility errors."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.errors import IdentifiabilityWarning
from sensorless.excitation import random_fourier
from sensorless.identification import identify
from sensorless.identification.verdicts import compute_verdicts, linear_split, regulariser_hessian
from sensorless.regressor.compress import compress
from sensorless.regressor.normal_equations import NormalEquations
from sensorless.regressor.terms import ModelStructure
from sensorless.testing import perturbed_truth, synthetic_trajectory

ROBOT = ["--robot", "panda", "--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]
RATE, T = 100.0, 40.0


def _run(args):
    return CliRunner().invoke(app, [str(a) for a in args])


def one_joint_at_a_time(robot, seed: int = 0):
    """A Fourier motion in which, in each of n segments, only one joint moves (the others held mid-range)."""
    m = random_fourier(robot, rng=seed, base_freq=0.1).sample(RATE, T)
    q, v, a = np.tile(m.q.mean(axis=0), (len(m), 1)), np.zeros_like(m.v), np.zeros_like(m.a)
    for j, seg in enumerate(np.array_split(np.arange(len(m)), q.shape[1])):
        q[seg, j], v[seg, j], a[seg, j] = m.q[seg, j], m.v[seg, j], m.a[seg, j]
    return m.with_(q=q, v=v, a=a)


@pytest.fixture(scope="module")
def arm_logs(tmp_path_factory, panda):
    d = tmp_path_factory.mktemp("verdict_logs")
    truth = perturbed_truth(panda, rng=1)
    logs = {"onejoint": synthetic_trajectory(truth, one_joint_at_a_time(panda), noise_std=0.1, rng=0),
            "full": synthetic_trajectory(truth, random_fourier(panda, rng=5, base_freq=0.1).sample(RATE, T),
                                         noise_std=0.1, rng=1),
            "heldout": synthetic_trajectory(truth, random_fourier(panda, rng=7, base_freq=0.1).sample(RATE, T),
                                            noise_std=0.1, rng=2)}
    for k, t in logs.items():
        write_npz(t, d / f"{k}.npz")
    return d, logs


# ---- the math -----------------------------------------------------------------------------------
def test_linear_split_is_the_regularised_solution_of_a_quadratic_problem(rng):
    """Oracle: for πᵀAπ − 2bᵀπ + (π−π0)ᵀH(π−π0) without constraints, φ_data + φ_prior = aᵀπ̂ (A singular)."""
    p = 12
    W = rng.normal(size=(40, p)) @ np.diag([1.0] * 8 + [0.0] * 4)  # 4 unseen directions
    A, b = W.T @ W, W.T @ rng.normal(size=40)
    L = rng.normal(size=(p, p))
    H, pi0 = 0.1 * L @ L.T + 1e-3 * np.eye(p), rng.normal(size=p)
    pi_hat = np.linalg.solve(A + H, b + H @ pi0)
    a = rng.normal(size=(5, p))
    d, pr = linear_split(A, b, H, pi0, a)
    np.testing.assert_allclose(d + pr, a @ pi_hat, rtol=1e-8, atol=1e-8)
    # in the unseen directions the value is the prior's alone
    e = np.zeros((1, p))
    e[0, -1] = 1.0
    dd, pp = linear_split(A, b, H * 1e-6, pi0, e)  # weak prior
    assert abs(dd[0]) < 1e-6 * abs(pp[0]) + 1e-12 or abs(pp[0]) > 0


def test_regulariser_hessian_reproduces_the_lmi_solution(panda):
    """The pullback regulariser mapped to π coordinates: with no active constraint the LMI's
    estimate equals (A+H)⁻¹(b+Hπ0) (solver accuracy)."""
    truth = perturbed_truth(panda, rng=2)
    log = synthetic_trajectory(truth, random_fourier(panda, rng=3, base_freq=0.2).sample(100, 20.0), noise_std=0.05, rng=4)
    s = ModelStructure(panda, joint_terms=("fv", "offset"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(s, log, method="lmi", gamma=1e-2, ellipsoids=False, weights=None)
    assert not res.diagnostics["verdicts"]["active_bounds"]["bodies"]
    ne = compress(s, log)
    A, b, c = ne.total()
    H = regulariser_hessian(s, s.prior(), res.diagnostics["lmi"], 1e-2, "pullback", A, c, ne.n_samples)
    fit = np.array(res.diagnostics["presented"].get("fit_parameters", res.parameters))  # the LMI's own solution
    d, pr = linear_split(A, b, H, s.prior(), np.eye(s.n_params))
    rel = np.abs(d + pr - fit) / (np.abs(fit) + 1e-3 * np.abs(fit).max())
    assert np.median(rel) < 1e-4 and rel.max() < 1e-3, rel.max()


def test_full_rank_noise_free_problem_every_quantity_is_data(panda, rng):
    s = ModelStructure(panda, joint_terms=("fv", "fc"))
    p = s.n_params
    W = rng.normal(size=(20 * p, p))
    pi = s.prior() + 0.01 * rng.normal(size=p)
    y = W @ pi + 1e-9 * rng.normal(size=len(W))
    ne = NormalEquations((W.T @ W)[None], (W.T @ y)[None], np.array([y @ y]), np.array([y.min()]),
                         np.array([y.max()]), np.array([y.sum()]), len(W))
    v = compute_verdicts(s, ne, np.linalg.solve(W.T @ W, W.T @ y), method="ols")
    got = [e["verdict"] for g in ("bodies", "joints") for ent in v[g].values() for e in ent.values()]
    assert got and set(got) == {"data"}, set(got)
    # the same equations with two body columns never seen: those bodies' masses are not "data"
    W2 = W.copy()
    W2[:, [0, 10]] = 0.0
    ne2 = NormalEquations((W2.T @ W2)[None], (W2.T @ y)[None], np.array([y @ y]), np.array([y.min()]),
                          np.array([y.max()]), np.array([y.sum()]), len(W2))
    v2 = compute_verdicts(s, ne2, pi, method="svd")
    b0, b1 = panda.body_names[:2]
    assert v2["bodies"][b0]["mass"]["verdict"] == "undetermined" and v2["bodies"][b0]["mass"]["std_data"] is None
    assert v2["bodies"][b1]["mass"]["verdict"] == "undetermined"
    assert v2["bodies"][panda.body_names[3]]["mass"]["verdict"] == "data"


# ---- acceptance: one joint at a time, full motion ---------------------------------------------------
def test_one_joint_at_a_time_keeps_unexcited_masses_near_the_prior(arm_logs, tmp_path, panda):
    from sensorless import load_robot

    d, logs = arm_logs
    out = tmp_path / "m"
    r = _run(["identify", *ROBOT, "--data", d / "onejoint.npz", "--validate", d / "heldout.npz", "--out", out,
              "--no-plot", "--joint-terms", "fv,fc,offset"])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "result.json").read_text())
    v = doc["diagnostics"]["verdicts"]
    m0 = panda.inertial_parameters()[0::10]
    m_reg = np.array([doc["parameters"][f"{b}.m"] for b in panda.body_names])
    urdf = load_robot(out / "model.urdf").inertial_parameters()
    m_urdf = urdf[0::10]
    not_data = [k for k, b in enumerate(panda.body_names) if v["bodies"][b]["mass"]["verdict"] != "data"]
    assert not_data  # individual arm masses regroup: the data never determine them all
    shown_prior = doc["diagnostics"]["presented"]["prior_mass_bodies"]
    assert len(shown_prior) >= len(not_data) - 1  # the prior's mass reached along the null space (6 of 7 here)
    for k in not_data:
        b = panda.body_names[k]
        assert v["bodies"][b]["mass"]["verdict"] == ("prior" if b in shown_prior else "undetermined")
        assert 0.5 < m_urdf[k] / m0[k] < 2.0 and 0.5 < m_reg[k] / m0[k] < 2.0, (b, m_urdf[k], m_reg[k], m0[k])
        if b in shown_prior:
            assert m_urdf[k] == pytest.approx(m0[k], rel=1e-9)  # `prior`: the value written is the prior's
    assert "the prior's mass is written" in (out / "model.urdf").read_text()
    # one presented model: the URDF predicts exactly what result.json's parameters do
    s, s2 = ModelStructure(panda, joint_terms=()), ModelStructure(load_robot(out / "model.urdf"), joint_terms=())
    te = logs["heldout"].take(slice(0, 50))
    params = np.array([doc["parameters"][k] for k in s.labels])
    np.testing.assert_allclose(s2.torques(s2.prior(), te), s.torques(params, te), atol=1e-6)
    # the table shows the written (prior) mass with its verdict
    for k in not_data:
        if panda.body_names[k] in shown_prior:
            row = next(ln for ln in r.output.splitlines() if f"panda_link{k + 1} " in ln)
            assert f"{m_urdf[k]:.3f}" in row and "prior" in row, row
    # held-out on a full motion: not worse than 1.5× the prior (CAD) model, in fact better
    val = doc["validation"][str(d / "heldout.npz")]
    assert val["lmi"]["mean_nrmse"] < val["cad"]["mean_nrmse"], (val["lmi"]["mean_nrmse"], val["cad"]["mean_nrmse"])
    # --urdf-values regularised writes result.json's values
    out2 = tmp_path / "m2"
    r = _run(["identify", *ROBOT, "--data", d / "onejoint.npz", "--out", out2, "--no-plot", "--gamma",
              str(doc["diagnostics"]["gamma"]), "--joint-terms", "fv,fc,offset", "--urdf-values", "regularised"])
    assert r.exit_code == 0, r.output
    doc2 = json.loads((out2 / "result.json").read_text())
    m2 = np.array([doc2["parameters"][f"{b}.m"] for b in panda.body_names])
    np.testing.assert_allclose(load_robot(out2 / "model.urdf").inertial_parameters()[0::10], m2, rtol=1e-9)


def test_full_motion_held_out_nrmse_within_prior_models(arm_logs, tmp_path):
    d, _ = arm_logs
    out = tmp_path / "m"
    r = _run(["identify", *ROBOT, "--data", d / "full.npz", "--validate", d / "heldout.npz", "--out", out, "--no-plot",
              "--joint-terms", "fv,fc,offset"])
    assert r.exit_code == 0, r.output
    val = json.loads((out / "result.json").read_text())["validation"][str(d / "heldout.npz")]
    assert val["lmi"]["mean_nrmse"] < 1.5 * val["cad"]["mean_nrmse"]
    assert val["lmi"]["mean_nrmse"] < 0.5 * val["cad"]["mean_nrmse"], (val["lmi"]["mean_nrmse"], val["cad"]["mean_nrmse"])


# ---- runaway guard ----------------------------------------------------------------------------------
def test_gamma_zero_cross_validation_win_does_not_pass_silently(arm_logs, panda, monkeypatch):
    from sensorless.identification import gamma as gamma_mod

    _, logs = arm_logs
    real = gamma_mod.cross_validate_gamma

    def zero_wins(*args, **kwargs):
        sel = real(*args, **{**kwargs, "gammas": (0.0, 1e-6)})
        sel.gamma = 0.0
        return sel

    monkeypatch.setattr(gamma_mod, "cross_validate_gamma", zero_wins)
    with pytest.warns(IdentifiabilityWarning, match="raised to the floor"):
        res = identify(panda, logs["onejoint"], method="lmi", gamma="auto", joint_terms=("fv", "fc", "offset"))
    g = res.diagnostics["gamma_guard"]
    assert g["applied"] and g["gamma_cv"] == 0.0 and res.diagnostics["gamma"] == g["floor"] > 0
    m, m0 = res.inertial_parameters[0::10], panda.inertial_parameters()[0::10]
    assert np.all((m / m0 > 0.5) & (m / m0 < 2.0)), m / m0


# ---- massless prior (dvrk_psm) ------------------------------------------------------------------------
def test_massless_prior_prints_no_body_as_identified_unless_determined(capsys):
    from sensorless.cli.identify_outputs import print_bodies
    from sensorless.robots import psm_structure

    import pinocchio as pin

    rng = np.random.default_rng(3)
    s = psm_structure(coulomb_smoothing=0.05)
    p = np.zeros(s.n_params)
    for k in range(s.robot.n_bodies):
        p[10 * k: 10 * k + 10] = pin.Inertia(rng.uniform(0.2, 1.0), rng.uniform(-0.1, 0.1, 3),
                                             np.diag(rng.uniform(1e-3, 1e-2, 3))).toDynamicParameters()
    mot = random_fourier(s.robot, rng=1, base_freq=0.2, harmonics=4).sample(100, 20.0)
    log = mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p + rng.normal(size=(len(mot), 7)) * 1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(s, log, method="lmi")
    v = res.diagnostics["verdicts"]["bodies"]
    verdicts = {b: e["mass"]["verdict"] for b, e in v.items()}
    assert "prior" not in verdicts.values()  # a massless prior fixes nothing
    assert "undetermined" in verdicts.values()
    for b, e in v.items():  # "data" only with a small data-alone std
        if e["mass"]["verdict"] == "data":
            assert e["mass"]["std_data"] is not None and e["mass"]["std_data"] < 0.2 * abs(e["mass"]["value"]) + 1e-9
    print_bodies(res)
    text = capsys.readouterr().out
    P = res.inertial_parameters.reshape(-1, 10)
    m_col = [ln.split("│")[3].strip() for ln in text.splitlines() if ln.startswith("│")]
    shown = [x for x in m_col if x and x != "—"]
    non_data = [k for k, b in enumerate(res.robot.body_names) if verdicts[b] != "data"]
    assert m_col.count("—") == len(non_data) and len(shown) == len(verdicts) - len(non_data), text
    assert not {f"{P[k, 0]:.3f}" for k in non_data} & set(shown)


# ---- plausibility ---------------------------------------------------------------------------------------
def test_plausibility_errors_name_the_quantity(arm_logs, panda):
    import copy

    from sensorless.errors import PlausibilityError
    from sensorless.identification.plausibility import check_plausibility, plausibility_problems

    _, logs = arm_logs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(panda, logs["full"], method="lmi", gamma=1e-3, joint_terms=("fv", "fc", "offset"))
    assert plausibility_problems(res) == []
    b = panda.body_names[3]

    def doctored(fn):
        r = copy.deepcopy(res)
        fn(r.parameters)
        return r

    nan = doctored(lambda p: p.__setitem__(5, np.nan))
    assert "is nan" in plausibility_problems(nan)[0] and res.labels[5] in plausibility_problems(nan)[0]
    heavy = doctored(lambda p: p.__setitem__(30, 100.0))
    # judged on what model.urdf would hold: with --urdf-values regularised the fitted values
    assert any(f"body '{b}' mass 100 kg" in m for m in plausibility_problems(heavy, urdf_values="regularised"))
    far = doctored(lambda p: p.__setitem__(slice(31, 34), p[30] * np.array([5.0, 0.0, 0.0])))
    assert any(f"body '{b}' CoM" in m for m in plausibility_problems(far, urdf_values="regularised"))
    total = doctored(lambda p: p.__setitem__(slice(0, 70, 10), 1.8 * p[0:70:10]))
    total.diagnostics["verdicts"]["robot"]["total_mass"]["verdict"] = "data"
    assert any("total mass" in m and "+80 %" in m for m in plausibility_problems(total))
    with pytest.raises(PlausibilityError, match="`accept=True`"):
        check_plausibility(heavy, urdf_values="regularised")
    assert check_plausibility(heavy, accept=True, urdf_values="regularised")


def test_cli_implausible_model_exits_2_without_output_unless_accepted(arm_logs, tmp_path):
    from sensorless.data import read_trajectory

    d, logs = arm_logs
    big = logs["full"].with_(tau=logs["full"].tau * 30.0)  # 30× torques: a 100 kg link (< 100×: the channel checks pass)
    write_npz(big, tmp_path / "big.npz")
    out = tmp_path / "m"
    args = ["identify", *ROBOT, "--data", tmp_path / "big.npz", "--out", out, "--no-plot", "--gamma", "1e-3",
            "--joint-terms", "fv,fc,offset"]
    r = _run(args)
    assert r.exit_code == 2 and "implausible model" in r.output and "mass" in r.output, r.output
    assert "--accept-implausible" in r.output and not out.exists()
    r = _run([*args, "--accept-implausible"])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "result.json").read_text())
    assert doc["diagnostics"]["implausible_accepted"]
    assert read_trajectory  # imported for symmetry with the other CLI tests
