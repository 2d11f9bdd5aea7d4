"""Cartesian force estimation: oracle against Pinocchio's RNEA with external forces,
damped behaviour at a singularity, reference frames, errors and the CLI."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from sensorless.errors import RobotModelError, ShapeMismatchError
from sensorless.estimation import (
    CartesianForceEstimator,
    damped_least_squares,
    external_torque,
    frame_jacobians,
)

FRAME = "panda_hand"


def _tau_from_wrench(robot, q: np.ndarray, frame: str, F: np.ndarray, reference: str) -> np.ndarray:
    """Joint torque balancing a wrench F applied at ``frame`` (the oracle: RNEA with fext).

    τ = rnea(q, 0, 0, fext = −F) − rnea(q, 0, 0) = Jᵀ F when the robot pushes with F on the world."""
    model, data = robot.model, robot.model.createData()
    fid = robot.frame_id(frame)
    fr = model.frames[fid]
    pin.framesForwardKinematics(model, data, q)
    f = pin.Force(F[:3], F[3:])
    if reference == "local":
        f_joint = fr.placement.act(f)
    elif reference == "local_world_aligned":
        R = data.oMf[fid].rotation
        f_joint = fr.placement.act(pin.Force(R.T @ F[:3], R.T @ F[3:]))
    else:  # world: wrench at the world origin, world axes
        f_joint = data.oMi[fr.parentJoint].actInv(f)
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    fext[fr.parentJoint] = -f_joint  # the environment pushes back with −F
    z = np.zeros(model.nv)
    return pin.rnea(model, data, q, z, z, fext) - pin.rnea(model, data, q, z, z)


def _random_configs(robot, n, rng):
    lo, hi = robot.position_limits()
    return robot.full_configuration(rng.uniform(0.7 * lo + 0.3 * hi, 0.3 * lo + 0.7 * hi, (n, len(lo))))


@pytest.mark.parametrize("reference", ["local", "world", "local_world_aligned"])
def test_known_wrench_is_recovered_exactly(panda, reference):
    rng = np.random.default_rng(0)
    Q = _random_configs(panda, 20, rng)
    F = rng.normal(size=(20, 6)) * [10, 10, 10, 1, 1, 1]
    tau = np.array([_tau_from_wrench(panda, Q[i], FRAME, F[i], reference) for i in range(20)])
    est = CartesianForceEstimator(panda, FRAME, reference, components="wrench")
    res = est.from_external_torque(Q, tau)
    assert np.all(res.damping == 0) and np.all(res.sigma_min > est.sigma_threshold)
    np.testing.assert_allclose(res.F, F, atol=1e-9)
    assert res.labels == ["fx", "fy", "fz", "mx", "my", "mz"]


@pytest.mark.parametrize("reference", ["local", "local_world_aligned"])
def test_pure_force_recovered_from_linear_jacobian(panda, reference):
    rng = np.random.default_rng(1)
    Q = _random_configs(panda, 15, rng)
    F = np.hstack([rng.normal(size=(15, 3)) * 5, np.zeros((15, 3))])
    tau = np.array([_tau_from_wrench(panda, Q[i], FRAME, F[i], reference) for i in range(15)])
    res = CartesianForceEstimator(panda, FRAME, reference).from_external_torque(Q, tau)
    np.testing.assert_allclose(res.F, F[:, :3], atol=1e-9)


def test_reference_frames_are_related_by_the_frame_rotation(panda):
    rng = np.random.default_rng(2)
    Q = _random_configs(panda, 5, rng)
    tau = rng.normal(size=(5, 7))
    loc = CartesianForceEstimator(panda, FRAME, "local").from_external_torque(Q, tau).F
    lwa = CartesianForceEstimator(panda, FRAME, "local_world_aligned").from_external_torque(Q, tau).F
    data = panda.model.createData()
    for i in range(5):
        pin.framesForwardKinematics(panda.model, data, Q[i])
        np.testing.assert_allclose(lwa[i], data.oMf[panda.frame_id(FRAME)].rotation @ loc[i], atol=1e-9)


def test_damped_solution_stays_bounded_at_a_singularity(ur5):
    q = np.array([[0.0, -np.pi / 2, 0.0, -np.pi / 2, 0.0, 0.0]])  # stretched elbow and aligned wrist
    rng = np.random.default_rng(3)
    tau = rng.normal(size=(1, 6))
    frame = ur5.model.frames[-1].name
    J = frame_jacobians(ur5, ur5.full_configuration(q), frame)[:, :, ur5.actuated_v_indices]
    assert np.linalg.svd(J[0], compute_uv=False)[-1] < 1e-9  # really singular
    lam = 0.05
    damped = damped_least_squares(J, tau, sigma_threshold=0.02, lambda_max=lam)
    assert damped.damping[0] == pytest.approx(lam)
    # exactly singular: the lost direction is unobservable (NaN and flagged), the rest stays bounded
    unobs = damped.unobservable[0]
    assert unobs.any() and not unobs.all() and np.isnan(damped.F[0, unobs]).all()
    assert np.linalg.norm(damped.F[0, ~unobs]) <= np.linalg.norm(tau) / (2 * lam) + 1e-12
    # near (not at) the singularity the undamped solution explodes, the damped one does not
    q_near = q + 1e-7
    Jn = frame_jacobians(ur5, ur5.full_configuration(q_near), frame)[:, :, ur5.actuated_v_indices]
    plain = damped_least_squares(Jn, tau, sigma_threshold=0.02, lambda_max=0.0)
    near = damped_least_squares(Jn, tau, sigma_threshold=0.02, lambda_max=lam)
    assert np.linalg.norm(plain.F) > 1e4 * np.linalg.norm(tau)
    assert np.linalg.norm(near.F) <= np.linalg.norm(tau) / (2 * lam) * (1 + 1e-9)


def test_damping_grows_continuously_as_sigma_min_drops():
    s = np.array([1.0, 0.5, 0.02, 0.01, 0.005, 0.0])
    J = np.zeros((len(s), 2, 3))
    J[:, 0, 0] = 1.0
    J[:, 1, 1] = s
    sol = damped_least_squares(J, np.ones((len(s), 3)), sigma_threshold=0.01, lambda_max=0.1)
    np.testing.assert_allclose(sol.sigma_min[:5], s[:5])
    lam = 0.1 * np.sqrt(1 - (s[4] / 0.01) ** 2)
    assert np.all(sol.damping[:4] == 0) and sol.damping[4] == pytest.approx(lam)
    np.testing.assert_allclose(sol.F[:4, 1], 1 / s[:4])  # exact inverse away from the singularity
    # σ = 0: that direction is unobservable (NaN, flagged), the other one is exact and undamped
    assert sol.unobservable[5].tolist() == [False, True] and np.isnan(sol.F[5, 1]) and sol.F[5, 0] == 1.0
    assert sol.sigma_min[5] == 1.0 and sol.damping[5] == 0


def test_external_torque_and_bad_inputs(panda):
    m = np.ones((4, 7))
    np.testing.assert_allclose(external_torque(3 * m, m, m), m)
    with pytest.raises(ShapeMismatchError):
        external_torque(m, np.ones((4, 6)))
    with pytest.raises(RobotModelError, match="unknown frame"):
        CartesianForceEstimator(panda, "no_such_frame")
    with pytest.raises(RobotModelError, match="reference"):
        CartesianForceEstimator(panda, FRAME, "body")
    with pytest.raises(RobotModelError, match="neither actuated nor passive"):
        CartesianForceEstimator(panda, FRAME, joints=["nope"])
    est = CartesianForceEstimator(panda, FRAME)
    with pytest.raises(ShapeMismatchError, match="tau_ext"):
        est.from_external_torque(panda.full_configuration(np.zeros((2, 7))), np.zeros((2, 6)))


def test_estimate_force_cli_recovers_a_known_tip_force(tmp_path, panda):
    """Identify a model from a free-space log, then recover a force applied in a second log."""
    import sensorless.cli.hybrid_force  # noqa: F401  (registers the command)
    from sensorless.cli import app
    from sensorless.data import write_npz
    from sensorless.excitation import random_fourier
    from sensorless.identification import identify
    from sensorless.regressor import ModelStructure
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    truth = perturbed_truth(panda, rng=0)
    free = synthetic_trajectory(truth, random_fourier(panda, rng=1).sample(100, 20.0), noise_std=0.01, rng=2)
    structure = ModelStructure(panda)
    result = identify(structure, free)
    result.save_json(tmp_path / "result.json")
    push = synthetic_trajectory(truth, random_fourier(panda, rng=3, position_fraction=0.5).sample(100, 5.0), noise_std=0.0, rng=4)
    t = push.t
    F = np.stack([5 * np.sin(t), 3 * np.cos(0.7 * t), -10 + 2 * np.sin(1.3 * t)], axis=1)  # world axes, at the hand
    Q = panda.full_configuration(push.q)
    tau_ext = np.array([_tau_from_wrench(panda, Q[i], FRAME, np.r_[F[i], 0, 0, 0], "local_world_aligned") for i in range(len(t))])
    write_npz(push.with_(tau=push.tau + tau_ext), tmp_path / "push.npz")
    out = tmp_path / "forces.npz"
    r = CliRunner().invoke(app, ["estimate-force", "--robot", "panda", "--lock", "panda_finger_joint1", "--lock",
                                 "panda_finger_joint2", "--model", str(tmp_path), "--data", str(tmp_path / "push.npz"),
                                 "--frame", FRAME, "--reference", "local_world_aligned", "--out", str(out)])
    assert r.exit_code == 0, r.output
    z = np.load(out)  # plain arrays, no pickle needed
    assert list(z["labels"]) == ["fx", "fy", "fz"]
    err = np.sqrt(((z["force"] - F) ** 2).mean(axis=0))
    assert np.all(err < 0.05 * np.ptp(F, axis=0).clip(min=1.0)), err
    # with a learned residual (trained on free-space data: it should change little)
    from sensorless.torque_models import PhysicalModel
    from sensorless.learning import HybridModel

    HybridModel(PhysicalModel.from_parameters(structure, result.parameters), window=2, hidden=(16,), seed=0, epochs=5).fit(free).save(tmp_path / "res")
    out2 = tmp_path / "forces2.npz"
    r = CliRunner().invoke(app, ["estimate-force", "--robot", "panda", "--lock", "panda_finger_joint1", "--lock",
                                 "panda_finger_joint2", "--model", str(tmp_path / "result.json"), "--data", str(tmp_path / "push.npz"),
                                 "--frame", FRAME, "--residual", str(tmp_path / "res"), "--out", str(out2)])
    assert r.exit_code == 0, r.output
    z2 = np.load(out2)
    assert not np.array_equal(z2["force"], z["force"])
    assert np.all(np.sqrt(((z2["force"] - F) ** 2).mean(axis=0)) < 0.1 * np.ptp(F, axis=0).clip(min=1.0))
    bad = CliRunner().invoke(app, ["estimate-force", "--robot", "panda", "--lock", "panda_finger_joint1", "--lock",
                                   "panda_finger_joint2", "--model", str(tmp_path), "--data", str(tmp_path / "push.npz"),
                                   "--frame", "nope", "--out", str(tmp_path / "x.npz")])
    assert bad.exit_code == 2 and "unknown frame 'nope'" in bad.output


# ---- issue 11: frame Jacobians through a transmission (the dVRK PSM in motor coordinates) --------
def _psm_thetas(n, rng):
    from sensorless.robots import PSM_LIMITS

    lo, hi = PSM_LIMITS["lower"], PSM_LIMITS["upper"]
    return rng.uniform(0.7 * lo + 0.3 * hi, 0.3 * lo + 0.7 * hi, (n, 7))


def test_psm_frame_jacobian_is_the_derivative_in_motor_coordinates():
    """J_θ = J_tree · ∂q/∂θ = J_tree G: oracle by central differences of the frame position in θ."""
    from sensorless.robots import psm_robot

    r = psm_robot()
    th = _psm_thetas(5, np.random.default_rng(0))
    J = frame_jacobians(r, th, "tool_tip", "local_world_aligned")
    assert J.shape == (5, 6, 7)
    model, data, fid = r.tree.model, r.tree.model.createData(), r.frame_id("tool_tip")

    def pos(t):
        pin.framesForwardKinematics(model, data, r.G @ t)
        return data.oMf[fid].translation.copy()

    h = 1e-6
    for i in range(5):
        fd = np.stack([(pos(th[i] + h * e) - pos(th[i] - h * e)) / (2 * h) for e in np.eye(7)], axis=1)
        np.testing.assert_allclose(J[i, :3], fd, atol=1e-7)
    assert np.abs(J[:, :3, 5:]).max() == 0.0  # the jaw motors do not move the wrist-pitch body


def test_psm_tip_force_recovered_from_motor_efforts():
    """Regression: CartesianForceEstimator crashed on the PSM ('CoordinateRobot' has no frame_id /
    ShapeMismatchError 12 vs 7). Oracle: RNEA of the tree with the tip force, mapped by Gᵀ."""
    from sensorless.robots import psm_robot

    r = psm_robot()
    rng = np.random.default_rng(1)
    th = _psm_thetas(15, rng)
    F = rng.normal(size=(15, 3)) * 2.0
    tau = np.array([r.G.T @ _tau_from_wrench(r.tree, r.G @ th[i], "tool_tip", np.r_[F[i], 0, 0, 0], "local_world_aligned")
                    for i in range(15)])
    est = CartesianForceEstimator(r, "tool_tip", "local_world_aligned", components="linear")
    res = est.from_external_torque(th, tau)
    np.testing.assert_allclose(res.F, F, atol=1e-8)
    # only the joints of the arm (drop the wrist motors)
    est3 = CartesianForceEstimator(r, "tool_tip", joints=["q1", "q2", "q3"])
    np.testing.assert_allclose(est3.from_external_torque(th, tau).F, F, atol=1e-8)


def test_psm_force_estimate_from_a_log_and_model():
    """estimate(traj, model) on the PSM: the model's torque is removed, the rest mapped to the tip."""
    from sensorless.torque_models import PhysicalModel
    from sensorless.robots import psm_robot, psm_structure

    s = psm_structure()
    rng = np.random.default_rng(2)
    p = rng.normal(size=s.n_params) * 0.01
    from sensorless.excitation import random_fourier

    mot = random_fourier(s.robot, rng=3, base_freq=0.3, harmonics=3, position_fraction=0.5).sample(50, 2.0)
    F = np.stack([np.sin(mot.t), np.cos(mot.t), 0.5 + 0 * mot.t], axis=1)
    tau_ext = np.array([s.G.T @ _tau_from_wrench(s.tree, s.G @ mot.q[i], "tool_tip", np.r_[F[i], 0, 0, 0],
                                                 "local_world_aligned") for i in range(len(mot))])
    log = mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p + tau_ext)
    res = CartesianForceEstimator(psm_robot(), "tool_tip").estimate(log, PhysicalModel.from_parameters(s, p))
    np.testing.assert_allclose(res.F, F, atol=1e-8)


# ---- unobservable force directions: NaN and flagged, never 0 -----------------------------------
def test_frame_on_the_base_is_unobservable_on_every_sample(panda):
    rng = np.random.default_rng(2)
    Q = _random_configs(panda, 10, rng)
    est = CartesianForceEstimator(panda, "panda_link0", "world")
    res = est.from_external_torque(Q, rng.normal(size=(10, panda.n_actuated)))
    assert res.unobservable.all() and np.isnan(res.F).all() and res.n_unobservable == 10


def test_only_the_direction_the_joints_cannot_produce_is_nan(panda):
    """Joint 1 alone (axis: world z) measures the moment about z, never about x or y: mz is
    recovered exactly, mx and my are NaN and flagged on every sample."""
    rng = np.random.default_rng(3)
    Q = _random_configs(panda, 8, rng)
    est = CartesianForceEstimator(panda, "panda_link3", "world", components="angular",
                                  joints=[panda.actuated_joints[0]])
    tau = np.zeros((8, panda.n_actuated))
    tau[:, 0] = rng.normal(size=8)
    res = est.from_external_torque(Q, tau)
    assert res.unobservable[:, :2].all() and not res.unobservable[:, 2].any()
    assert np.isnan(res.F[:, :2]).all()
    np.testing.assert_allclose(res.F[:, 2], tau[:, 0], atol=1e-12)


def test_cli_refuses_a_frame_whose_force_is_never_observable(panda, tmp_path):
    from sensorless.cli import app
    from sensorless.data import write_npz
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    lock = ["--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]
    truth = perturbed_truth(panda, rng=0)
    write_npz(synthetic_trajectory(truth, random_fourier(panda, rng=1).sample(100, 6.0), noise_std=0.05, rng=2),
              tmp_path / "log.npz")
    r = CliRunner().invoke(app, ["identify", "--robot", "panda", *lock, "--data", str(tmp_path / "log.npz"),
                                 "--method", "ols", "--joint-terms", "fv,fc,offset", "--no-plot", "--out",
                                 str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    args = ["estimate-force", "--robot", "panda", "--model", str(tmp_path / "m"), "--data", str(tmp_path / "log.npz"),
            *lock]
    r = CliRunner().invoke(app, [*args, "--frame", "panda_link0", "--out", str(tmp_path / "f0.npz")])
    assert r.exit_code == 2 and "unobservable" in r.output and not (tmp_path / "f0.npz").exists()
    r = CliRunner().invoke(app, [*args, "--frame", "panda_hand", "--out", str(tmp_path / "f1.npz")])
    assert r.exit_code == 0, r.output
    z = np.load(tmp_path / "f1.npz")
    assert z["unobservable"].shape == z["force"].shape and np.isfinite(z["force"][~z["unobservable"]]).all()


def test_force_figure_marks_the_unobservable_samples(ur5):
    """At the wrist singularity (wrist_2 = 0) the UR5 tool's wrench loses a direction: those samples are NaN
    and the figure marks each run (a red span, one tick per sample) on the components concerned only."""
    from sensorless.report import force_figure

    rng = np.random.default_rng(4)
    n = 400
    t = np.arange(n) * 0.01
    Q = np.tile([0.3, -1.0, 1.2, -0.5, 0.8, 0.2], (n, 1)) + 0.3 * np.sin(t)[:, None]
    Q[150:180, 4] = Q[300, 4] = 0.0
    est = CartesianForceEstimator(ur5, "tool0", "local_world_aligned", components="wrench")
    res = est.from_external_torque(Q, rng.normal(size=(n, 6)), t)
    assert res.unobservable[:, 2].sum() == 0 and (res.unobservable.sum(axis=0)[[0, 1, 3, 4, 5]] == 31).all()
    fig = force_figure(res)
    assert [a.get_ylabel() for a in fig.axes] == ["fx [N]", "fy [N]", "fz [N]", "mx [N·m]", "my [N·m]", "mz [N·m]"]
    for c, ax in enumerate(fig.axes):
        spans = [col for col in ax.collections if col.get_gid() == "unobservable"]
        ticks = [ln for ln in ax.get_lines() if ln.get_gid() == "unobservable_samples"]
        if c == 2:
            assert not spans and not ticks and "observable on every sample" in ax.get_title(loc="left")
            continue
        (span,) = spans
        assert len(span.get_paths()) == 2  # the runs 1.50–1.79 s and 3.00 s
        assert len(ticks[0].get_xdata()) == 31 and "31 of 400" in ax.get_title(loc="left")
        force = next(ln for ln in ax.get_lines() if ln.get_gid() == "force")
        assert np.isnan(force.get_ydata()[np.isin(force.get_xdata(), t[150:180])]).all()  # the trace breaks there
    assert "unobservable (NaN: no joint torque measures it)" in [x.get_text() for x in fig.legends[0].get_texts()]
