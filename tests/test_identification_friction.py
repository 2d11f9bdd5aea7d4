"""The friction law with a fitted low-speed transition (issue 27): fs tanh(v/w) − (fs − fc)(1 − e^{−(v/vs)²}) sgn v
+ fv v + o, w and vs chosen per joint in one compression pass with the BIC rule; older model files keep
the product law; six single-joint logs identified together give each joint the fc of its own log."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from sensorless.data.trajectory import Trajectory
from sensorless.identification.friction import WIDTH_GRID_SIZE, friction_curve
from sensorless.identification.friction_search import identify_friction
from sensorless.regressor import ModelStructure

TERMS = ("fv", "fc", "stribeck", "offset", "armature")
SMOOTH_WIDTH = 0.02  # rad/s: friction rises over ~0.03 rad/s, as measured on geared arms


def _ur5_log(sigma_v: float, seed: int = 3):
    """A 30 s, 100 Hz UR5 log (sums of sines): joints 0, 2, 4 have friction rising smoothly (width
    SMOOTH_WIDTH), joints 1, 3, 5 a sharp Coulomb/Stribeck law; the logged velocity has noise σ_v."""
    from sensorless.robot import load_robot

    robot = load_robot("ur5")
    rng = np.random.default_rng(seed)
    t = np.arange(0, 30, 0.01)
    n = robot.n_actuated
    f, ph, amp = rng.uniform(0.05, 0.3, (3, n)), rng.uniform(0, 2 * np.pi, (3, n)), rng.uniform(0.3, 0.8, (3, n))
    q = sum(amp[k] * np.sin(2 * np.pi * f[k] * t[:, None] + ph[k]) for k in range(3))
    v = sum(amp[k] * 2 * np.pi * f[k] * np.cos(2 * np.pi * f[k] * t[:, None] + ph[k]) for k in range(3))
    a = sum(-amp[k] * (2 * np.pi * f[k]) ** 2 * np.sin(2 * np.pi * f[k] * t[:, None] + ph[k]) for k in range(3))
    joints = list(robot.actuated_joints)
    width = {j: SMOOTH_WIDTH if k % 2 == 0 else 0.0 for k, j in enumerate(joints)}
    truth = ModelStructure(robot, joint_terms=TERMS, coulomb_smoothing=width,
                           stribeck_velocity=dict(zip(joints, rng.uniform(0.1, 0.2, n))))
    p = truth.prior()
    for j in joints:
        p[truth.joint_term_index(j, "fv")] = rng.uniform(0.5, 2)
        p[truth.joint_term_index(j, "fc")] = rng.uniform(1, 3)
        p[truth.joint_term_index(j, "stribeck")] = rng.uniform(0.5, 1.5)
    exact = Trajectory(t=t, q=q, v=v, a=a, tau=np.zeros_like(q), joint_names=joints)
    tau = truth.torques(p, exact) + rng.normal(0, 0.02, q.shape)
    return robot, truth, p, dataclasses.replace(exact, tau=tau, v=v + rng.normal(0, sigma_v, v.shape))


@pytest.mark.parametrize("sigma_v", [1e-5, 1e-3])
def test_fitted_width_recovered_where_friction_rises_smoothly_and_sharp_joints_stay_sharp(sigma_v):
    """A joint whose friction rises smoothly gets its width back (within a grid step); a sharp joint
    gets no transition wider than the noise-implied ε. With an encoder-grade velocity nothing tells
    widths below ε apart, and the BIC rule keeps the simpler law (w = ε) there."""
    robot, truth, p, log = _ur5_log(sigma_v)
    res, fit = identify_friction(ModelStructure(robot, joint_terms=TERMS), [log])
    step = (fit.width_grid[robot.actuated_joints[0]][-1] / fit.width_grid[robot.actuated_joints[0]][0]) ** (
        1 / (WIDTH_GRID_SIZE - 1))
    for k, j in enumerate(robot.actuated_joints):
        w, eps = fit.transition_width[j], fit.coulomb_smoothing[j]
        assert res.structure.smoothing_of(j) == (w or eps)  # the width the model uses
        if k % 2 == 0:
            assert w is not None and SMOOTH_WIDTH / step <= w <= SMOOTH_WIDTH * step, (j, w)
        elif sigma_v < 1e-4:
            assert w is None, (j, w, eps)  # the simpler law
        else:
            assert w is None or w <= eps, (j, w, eps)  # no smooth transition invented
        fc = res.parameters[res.structure.joint_term_index(j, "fc")]
        assert fc == pytest.approx(p[truth.joint_term_index(j, "fc")], rel=0.05)
    # the identified curve follows the smooth rise: at 0.5 w the friction is tanh(0.5) ≈ 46 % of fs (the
    # simpler law would give ≈ fs there, 2.2 times as much)
    v = np.full((1, robot.n_actuated), 0.5 * SMOOTH_WIDTH)
    ratio = friction_curve(res.structure, res.parameters, v)[0] / friction_curve(truth, p, v)[0]
    assert np.all(np.abs(ratio[0::2] - 1) < 0.25), ratio


def test_law_columns_and_shape():
    """Oracle: the Stribeck column is T − (1 − e^{−(v/vs)²}) sgn v; the curve rises over w to ≈ fs,
    decays to fc + fv v far above vs; the product law of older files is e^{−(v/vs)²} T."""
    from sensorless.robot import load_robot

    robot = load_robot("ur5")
    j = robot.actuated_joints[0]
    s = ModelStructure(robot, joint_terms=("fv", "fc", "stribeck"), coulomb_smoothing=0.01, stribeck_velocity=0.1)
    v = np.array([-2.0, -0.05, -0.003, 0.0, 0.003, 0.05, 0.3, 2.0])
    V = np.zeros((v.size, robot.nv))
    V[:, 0] = v
    F = s.joint_features(V, np.zeros_like(V))[:, 0]
    T, E = np.tanh(v / 0.01), np.exp(-((v / 0.1) ** 2))
    assert np.allclose(F[:, 1], T) and np.allclose(F[:, 2], T - (1 - E) * np.sign(v))
    old = dataclasses.replace(s, friction_law="product")
    assert np.allclose(old.joint_features(V, np.zeros_like(V))[:, 0, 2], E * T)
    p = np.zeros(s.n_params)
    fv, fc, dfs = 0.5, 2.0, 1.0
    for t, val in (("fv", fv), ("fc", fc), ("stribeck", dfs)):
        p[s.joint_term_index(j, t)] = val
    curve = friction_curve(s, p, v[:, None] * np.eye(robot.n_actuated)[0])[:, 0]
    mirror = friction_curve(s, p, -v[:, None] * np.eye(robot.n_actuated)[0])[:, 0]
    assert curve[3] == 0 and np.allclose(curve, -mirror)  # odd, 0 at rest
    assert curve[5] == pytest.approx(fc + dfs * np.exp(-0.25) + fv * 0.05, rel=1e-3)  # rose to ≈ fs, decaying
    assert curve[-1] == pytest.approx(fc + fv * 2.0, rel=1e-9)  # far above vs: Coulomb + viscous


def test_model_files_without_the_law_key_keep_the_product_law(tmp_path):
    """result.json written before the fitted width (no settings.friction_law) is evaluated with the
    product law it was fitted with; a new file records "blend" and round-trips."""
    from sensorless.identification.artifact import structure_from_settings

    robot, truth, p, log = _ur5_log(1e-5)
    settings = truth.settings()
    assert settings["friction_law"] == "blend"
    assert structure_from_settings(settings, {}, robot).friction_law == "blend"
    old = {k: v for k, v in settings.items() if k != "friction_law"}
    assert structure_from_settings(old, {}, robot).friction_law == "product"
    assert structure_from_settings({"joint_terms": ["fv", "fc"]}, {}, robot).friction_law == "blend"  # no Stribeck
    from sensorless.errors import ParameterError
    from sensorless.identification.artifact_schema import Checker, check_structure_settings

    with pytest.raises(ParameterError, match="friction_law"):
        check_structure_settings(Checker(tmp_path / "result.json"), {**settings, "friction_law": "magic"})


def test_single_joint_logs_together_give_each_joint_the_fc_of_its_own_log(tmp_path):
    """Six simulated single-joint logs of a UR10 with Stribeck friction, identified together (as the
    CLI does with six --data files): every joint's fc within 5 % of the fit of its own log alone."""
    from sensorless.data.prepare import load_log
    from sensorless_studies.simulation.current_arm import drive_gains_for, simulate, truth_model

    robot, truth = truth_model("ur10", 0, stribeck=True, friction_scale=4.0)
    K = drive_gains_for(robot)
    joints = list(robot.actuated_joints)
    (tmp_path / "gains.json").write_text(json.dumps(dict(zip(joints, map(float, K)))))
    logs = []
    for k, j in enumerate(joints):
        simulate(robot, truth, K, seed=10 + k, motion=8.0, idle_start=1.0, idle_end=1.0, ramp=1.0,
                 moving=[j]).to_csv(tmp_path / f"{j}.csv", index=False)
        logs.append(load_log(tmp_path / f"{j}.csv", robot, "q=pos_{joint};v=vel_{joint};tau=i_{joint}", None, None,
                             None, 1, gains=str(tmp_path / "gains.json")))
    assert all(np.ptp(t.q, axis=0)[k] > 0.1 and np.sum(np.ptp(t.q, axis=0) > 1e-3) == 1 for k, t in enumerate(logs))
    res, fit = identify_friction(ModelStructure(robot, joint_terms=TERMS), logs, identify_kwargs={"method": "lmi"})
    for k, j in enumerate(joints):
        alone, _ = identify_friction(ModelStructure(robot, joint_terms={j: TERMS, "*": ()}), [logs[k]],
                                     identify_kwargs={"method": "lmi"})
        fc_all = res.parameters[res.structure.joint_term_index(j, "fc")]
        fc_one = alone.parameters[alone.structure.joint_term_index(j, "fc")]
        assert fc_all == pytest.approx(fc_one, rel=0.05), (j, fc_all, fc_one)
        assert fc_all == pytest.approx(truth.fc[k], rel=0.1), (j, fc_all, truth.fc[k])
