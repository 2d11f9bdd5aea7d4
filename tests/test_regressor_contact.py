"""Contact null-space projection: projector oracles and recovery on rigid-contact data."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.data import Trajectory
from sensorless.errors import DataError, RobotModelError
from sensorless.identification import identify
from sensorless.regressor import ContactStructure, ModelStructure, compress, null_space_projector
from sensorless.testing import perturbed_truth

FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")


def test_projector_matches_per_sample_pinv_and_handles_rank_deficiency(rng):
    N, m, nv = 50, 12, 18
    J = rng.normal(size=(N, m, nv))
    J[::5, 3:6] = J[::5, 0:3]  # duplicated rows: rank-deficient stance
    J[1::7, :] = 0.0  # flight
    for method in ("cholesky", "svd"):
        P = null_space_projector(J, method=method)
        for i in range(N):
            ref = np.eye(nv) - np.linalg.pinv(J[i], rcond=1e-10) @ J[i]
            np.testing.assert_allclose(P[i], ref, atol=1e-9)
        np.testing.assert_allclose(np.matmul(P, J.transpose(0, 2, 1)), 0.0, atol=1e-9)
        np.testing.assert_allclose(np.matmul(P, P), P, atol=1e-9)
        np.testing.assert_allclose(P[1], np.eye(nv))


def _rigid_contact_log(robot, truth, n, rng, with_forces=False):
    """Samples from Pinocchio's contact-constrained forward dynamics (feet in random subsets)."""
    model = truth.robot.model.copy()
    act = robot.actuated_v_indices
    model.armature[:] = 0.0
    model.armature[act] = truth.armature
    data = model.createData()
    fids = [model.getFrameId(f) for f in FEET]
    q_list, v_list, a_list, tau_list, flags, forces = [], [], [], [], [], []
    for i in range(n):
        q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        q[3:7] = pin.Quaternion(pin.SE3.Random().rotation).coeffs()
        active = rng.random(4) < 0.7 if i % 6 else np.zeros(4, bool)
        pin.computeJointJacobians(model, data, q)
        J = np.concatenate([pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
                            for fid, on in zip(fids, active) if on] or [np.zeros((0, model.nv))])
        v = rng.normal(size=model.nv)
        if J.shape[0]:
            v = v - np.linalg.pinv(J) @ (J @ v)  # consistent with sticking contacts
        tau = rng.normal(size=len(act)) * 2.0
        vj = v[act]
        applied = np.zeros(model.nv)
        applied[act] = tau - truth.fv * vj - truth.fc * np.sign(vj) - truth.offset
        if J.shape[0]:
            a = pin.forwardDynamics(model, data, q, v, applied, J, np.zeros(J.shape[0]))
            lam = data.lambda_c.copy()
        else:
            a = pin.aba(model, data, q, v, applied)
            lam = np.zeros(0)
        f = np.zeros((4, 3))
        f[active] = lam.reshape(-1, 3)
        q_list.append(q), v_list.append(v), a_list.append(a), tau_list.append(tau), flags.append(active), forces.append(f)
    Q, V, A = map(np.array, (q_list, v_list, a_list))
    qidx = [robot.q_index(j) for j in robot.joint_names]
    vidx = [robot.v_index(j) for j in robot.joint_names]
    extras = {"contact": np.array(flags)}
    if with_forces:
        extras["contact_forces"] = np.array(forces)
    return Trajectory(t=np.arange(n) * 0.01, q=Q[:, qidx], v=V[:, vidx], a=A[:, vidx], tau=np.array(tau_list),
                      base_q=Q[:, :7], base_v=V[:, :6], base_a=A[:, :6], joint_names=robot.joint_names,
                      extras=extras, source="<constrained dynamics>")


@pytest.fixture(scope="module")
def rigid(solo12):
    rng = np.random.default_rng(0)
    truth = perturbed_truth(solo12, rng=4)
    return truth, _rigid_contact_log(solo12, truth, 400, rng, with_forces=True)


def test_lambda_sign_and_projected_residual_is_zero(solo12, rigid):
    """The log satisfies P (Y π + Sᵀ Φ φ − Sᵀ τ) = 0 with the true parameters."""
    truth, log = rigid
    s = ContactStructure(solo12, contact_frames=FEET)
    pi = truth.parameters(s.joint_terms)
    res = s.torques(pi, log) - s.target(log)
    assert np.abs(res).max() < 1e-8 * np.abs(s.target(log)).max()
    # without projection the residual is the contact wrench term: large
    plain = ModelStructure(solo12)
    assert np.abs(plain.torques(pi, log) - plain.target(log)).max() > 1e-2


def test_projected_regression_recovers_identifiable_parameters(solo12, rigid):
    truth, log = rigid
    s = ContactStructure(solo12, contact_frames=FEET)
    ne = compress(s, log, chunk=128)
    res = identify(s, ne, method="svd", svd_rcond=1e-9)
    pi = truth.parameters(s.joint_terms)
    A, _, _ = ne.total()
    lam, U = np.linalg.eigh(A)
    Ur = U[:, lam > 1e-10 * lam.max()]  # identifiable directions of this data set
    err = np.linalg.norm(Ur.T @ (res.parameters - pi)) / np.linalg.norm(Ur.T @ pi)
    assert err < 1e-6
    # these are exactly the structural base parameters here (feet subsets + flight excite all)
    assert np.linalg.norm(res.base_values - res.base.base(pi)) < 1e-6 * np.linalg.norm(res.base.base(pi))


def test_wrench_mode_with_measured_forces(solo12, rigid):
    truth, log = rigid
    s = ContactStructure(solo12, contact_frames=FEET, mode="wrench")
    res = identify(s, log)
    true_base = res.base.base(truth.parameters(s.joint_terms))
    assert np.linalg.norm(res.base_values - true_base) < 1e-6 * np.linalg.norm(true_base)


def test_clear_errors(solo12, panda, rigid):
    _, log = rigid
    ContactStructure(panda, contact_frames=("panda_link7",))  # a fixed base in contact: its joint rows are projected
    with pytest.raises(RobotModelError, match="fixed base"):
        ContactStructure(panda, contact_frames=("panda_link7",), mode="wrench", contact_rows="base")
    with pytest.raises(RobotModelError, match="unknown frame"):
        ContactStructure(solo12, contact_frames=("LEFT_FOOT",))
    s = ContactStructure(solo12, contact_frames=FEET)
    bad = log.with_(extras={"contact": np.ones((len(log), 3), bool)})
    with pytest.raises(DataError, match="contact flags"):
        s.target(bad)
    w = ContactStructure(solo12, contact_frames=FEET, mode="wrench")
    with pytest.raises(DataError, match="contact_forces"):
        w.target(log.with_(extras={"contact": log.extras["contact"]}))


def test_identifiability_report_all_feet_in_contact_loses_directions(solo12):
    """Stance-only data (all four feet down) excite fewer base parameters than mixed data."""
    from sensorless.identification import base_parameters, identifiability_report

    rng = np.random.default_rng(3)
    truth = perturbed_truth(solo12, rng=1)
    log = _rigid_contact_log(solo12, truth, 200, rng)
    stance = log.with_(extras={"contact": np.ones((len(log), 4), bool)})
    s = ContactStructure(solo12, contact_frames=FEET)
    base = base_parameters(s)
    mixed = identifiability_report(compress(s, log), base)
    # the stance log is not physically consistent with all feet down, but the regressor rank only
    # depends on the kinematics, which is what the report is about
    only = identifiability_report(compress(s, stance), base)
    assert mixed["n_base_excited"] == base.rank
    assert only["n_base_excited"] < mixed["n_base_excited"]
    assert len(only["not_excited"]) == base.rank - only["n_base_excited"]


def test_cli_identifies_a_legged_robot_from_npz_logs_with_contact_flags(solo12, tmp_path):
    """`sensorless identify --contact-frames …` on simulated Solo12 logs (q, v at 100 Hz, τ,
    contact flags in the NPZ): the projected LMI model is physically consistent, beats the CAD
    model on a held-out log, recovers the total mass, and `predict` rebuilds the projection."""
    import json

    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless.data import read_trajectory, write_npz
    from sensorless.torque_models import load_parameters
    from sensorless_studies.experiments.contact_id import prepare_log
    from sensorless_studies.simulation.quadruped import make_truth, simulate

    truth = make_truth(solo12, 0)
    paths = {}
    for name, (scen, kw, seed) in {"train": ("trot", {"speed": 0.2}, 1), "val": ("wobble", {}, 2)}.items():
        traj, gt = simulate(scen, solo12, duration=6.0, seed=seed, truth=truth, **kw)
        paths[name] = write_npz(prepare_log(traj), tmp_path / f"{name}.npz")
    back = read_trajectory(paths["val"], robot=solo12)
    assert back.extras["contact"].dtype == bool and back.extras["contact"].shape == (len(back), 4)
    out = tmp_path / "id"
    args = ["identify", "--robot", "solo12", "--data", paths["train"], "--validate", paths["val"], "--out", out,
            "--contact-frames", ",".join(FEET), "--contact-offset", gt.foot_radius, "--method", "lmi",
            "--gamma", "1e-3", "--joint-terms", "fv,fc,armature", "--coulomb-smoothing", "0.02"]
    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "result.json").read_text())
    assert doc["settings"]["contact_frames"] == list(FEET)
    # the torque figures go one per limb (issue 24): the 6 base rows, then each leg's 3 joints
    assert sorted(p.name for p in out.glob("torques*.png")) == [f"torques_{g}.png" for g in ("FL", "FR", "HL", "HR",
                                                                                             "base")]
    assert doc["physical_consistency"]["inconsistent_bodies"] == []
    val = doc["validation"][str(paths["val"])]
    assert val["lmi"]["mean_rmse"] < 0.9 * val["cad"]["mean_rmse"]  # measured 0.049 vs 0.060 (SG accelerations)
    structure, params = load_parameters(out / "result.json", solo12)
    assert isinstance(structure, ContactStructure) and structure.contact_offset == gt.foot_radius
    m_true = truth.parameters(())[0::10].sum()
    # 600 trot samples, accelerations from 100 Hz velocities: measured 6.4 % (prior 2.6 %)
    assert abs(params[: 10 * solo12.n_bodies][0::10].sum() / m_true - 1) < 0.1
    # a contact frame that does not exist is a one-line error, and no output is left behind
    bad = CliRunner().invoke(app, [str(a) for a in args[:-14]] + ["--out", str(tmp_path / "bad"), "--contact-frames", "FL_FOOT,NOPE"])
    assert bad.exit_code != 0 and "NOPE" in bad.output and not (tmp_path / "bad").exists()


def test_contacts_that_leave_no_equation_are_refused_with_the_reason(solo12, rigid):
    """Four flat feet held on the ground constrain all 18 directions (the clamped-leg case): the
    projection keeps none of the torques' energy, and identify says so instead of fitting noise."""
    from sensorless.errors import ExcitationError

    truth, log = rigid
    clamped = log.with_(extras={**log.extras, "contact": np.ones_like(log.extras["contact"])})
    s = ContactStructure(solo12, contact_frames=FEET, contact_dims=(6, 6, 6, 6))
    with pytest.raises(ExcitationError, match=r"projection keeps .* % of the logged torques' energy.*FL_FOOT"):
        identify(s, clamped, method="lmi", gamma=1e-3)
    identify(ContactStructure(solo12, contact_frames=FEET), log, method="svd")  # the same log, point feet: fine


def test_a_robot_held_still_is_refused(panda):
    from sensorless.errors import ExcitationError

    truth = perturbed_truth(panda, rng=0)
    n = 500
    q = np.tile(np.array([0.1, -0.3, 0.2, -1.5, 0.1, 1.2, 0.3]), (n, 1))
    z = np.zeros_like(q)
    tau = truth.torques(panda.full_configuration(q), panda.full_velocity(z), panda.full_velocity(z))
    still = Trajectory(t=np.arange(n) * 0.01, q=q, v=z, a=z, tau=tau + np.random.default_rng(0).normal(0, 0.01, tau.shape),
                       joint_names=panda.joint_names)
    with pytest.raises(ExcitationError, match="no joint moves"):
        identify(panda, still, joint_terms=("offset",), method="lmi", gamma=1e-3)
