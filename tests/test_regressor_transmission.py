"""Transmissions and drive terms: oracle tests against independent computations.

Every regressor here is checked as W(θ, θ̇, θ̈) π against a computation that does not use
the regressor: Pinocchio RNEA of the tree (inertias set from π) at q = Gθ + q₀, mapped by
Gᵀ, plus spring / rotor-inertia / friction forces computed directly, to 1e-9.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.data import Trajectory
from sensorless.errors import JointNameError, RobotModelError
from sensorless.excitation import FourierTrajectory
from sensorless.identification import base_parameters, identify
from sensorless.regressor import compress
from sensorless.regressor.drive_terms import DriveTerm
from sensorless.regressor.transmission import (
    TransmissionStructure,
    add_body_joint,
    coupling_matrix,
)
from sensorless.robot import Robot

RNG = np.random.default_rng(7)


def _rot(axis: str, a: float) -> np.ndarray:
    return pin.utils.rotate(axis, a)


def parallelogram_arm(counterweight: bool = False) -> tuple[Robot, np.ndarray, tuple[str, ...]]:
    """Yaw, pitch with a parallelogram (two links slaved to ±q2), insertion, and a
    cable-coupled 2-DoF wrist driven by two motors (G block = a full 2×2 matrix)."""
    m = pin.Model()
    j1 = add_body_joint(m, 0, "yaw", pin.SE3(_rot("x", np.pi / 2), np.zeros(3)))
    pitch_placement = pin.SE3(_rot("x", -np.pi / 2), np.array([0.1, 0.0, 0.0]))
    j2 = add_body_joint(m, j1, "pitch", pitch_placement)
    j3 = add_body_joint(m, j2, "par_front", pin.SE3(np.eye(3), np.array([0.05, 0.02, 0.0])))
    j4 = add_body_joint(m, j3, "par_bottom", pin.SE3(np.eye(3), np.array([0.30, 0.0, 0.0])))
    j5 = add_body_joint(m, j4, "insertion", pin.SE3(_rot("x", -np.pi / 2), np.array([0.04, 0.0, 0.1])), kind="prismatic")
    j6 = add_body_joint(m, j5, "wrist_pitch", pin.SE3(_rot("x", np.pi / 2), np.array([0.0, 0.0, 0.2])))
    add_body_joint(m, j6, "wrist_yaw", pin.SE3(_rot("x", -np.pi / 2), np.array([0.01, 0.0, 0.0])))
    if counterweight:  # its own joint on the pitch axis, turned by π, slaved to q2: rigid with the pitch link
        add_body_joint(m, j1, "counterweight", pitch_placement * pin.SE3(_rot("z", np.pi), np.zeros(3)))
    for j in range(1, m.njoints):
        m.inertias[j] = pin.Inertia.Random()
    tree = Robot(m, name="parallelogram_arm")
    coords = ("q1", "q2", "q3", "m4", "m5")
    rules = {
        "yaw": {"q1": 1.0},
        "pitch": {"q2": 1.0},
        "par_front": {"q2": -1.0},
        "par_bottom": {"q2": 1.0},
        "insertion": {"q3": 1.0},
        "wrist_pitch": {"m4": 1.02},  # coupled wrist: joints = M · motors
        "wrist_yaw": {"m4": -0.83, "m5": 1.22},
    }
    if counterweight:
        rules["counterweight"] = {"q2": 1.0}
    return tree, coupling_matrix(tree.joint_names, coords, rules), coords


def drives(n: int = 5) -> list[DriveTerm]:
    e = np.eye(n)
    return [
        DriveTerm("q1", e[0], ("fv", "fc", "offset")),
        DriveTerm("q4spring", e[3], ("spring",), s0=0.1),
        DriveTerm("m4", e[3], ("fv", "fc", "offset", "inertia")),
        DriveTerm("m5", e[4], ("fv", "inertia")),
        DriveTerm("jaw", 1.22 * e[4] - 0.83 * e[3], ("fv", "fc", "offset")),  # coupled friction
    ]


def random_states(n_coord: int, N: int = 40):
    return RNG.normal(size=(N, n_coord)), RNG.normal(size=(N, n_coord)) * 2, RNG.normal(size=(N, n_coord)) * 5


def oracle(structure: TransmissionStructure, params: np.ndarray, th, thd, thdd, smoothing: float = 0.0) -> np.ndarray:
    """Gᵀ · RNEA(tree with π) + Σ_d g_d f_d, computed without any regressor."""
    tree, G = structure.tree, structure.G
    model = tree.model.copy()
    for b in tree.body_names:
        model.inertias[tree.joint_id(b)] = pin.Inertia.Zero()
    for k, b in enumerate(structure.robot.body_names):
        model.inertias[tree.joint_id(b)] = pin.Inertia.FromDynamicParameters(params[10 * k : 10 * k + 10])
    data = model.createData()
    q, v, a = th @ G.T + structure.offset, thd @ G.T, thdd @ G.T
    out = np.array([G.T @ pin.rnea(model, data, q[i], v[i], a[i]) for i in range(len(th))])
    for d, vals in structure.drive_values(params).items():
        drv = next(x for x in structure.drives if x.name == d)
        s, sd, sdd = th @ drv.g + drv.s0, thd @ drv.g, thdd @ drv.g
        sgn = np.sign(sd) if smoothing <= 0 else np.tanh(sd / smoothing)
        f = (vals.get("fv", 0) * sd + vals.get("fc", 0) * sgn + vals.get("offset", 0)
             + vals.get("inertia", 0) * sdd + vals.get("k", 0) * s - vals.get("k_rest", 0))
        out += f[:, None] * drv.g[None, :]
    return out[:, structure._row_idx]


def random_params(structure: TransmissionStructure) -> np.ndarray:
    p = structure.prior()
    p[structure.n_body_params :] = RNG.normal(size=structure.n_params - structure.n_body_params)
    return p


@pytest.fixture(scope="module")
def arm():
    return parallelogram_arm()


def test_parallelogram_and_coupled_wrist_regressor_matches_mapped_rnea(arm):
    tree, G, coords = arm
    s = TransmissionStructure(tree, G, coords)
    th, thd, thdd = random_states(len(coords))
    p = s.prior()
    assert np.max(np.abs(s.evaluate(th, thd, thdd) @ p - oracle(s, p, th, thd, thdd))) < 1e-9
    # and with other (random, physically consistent) inertias
    p2 = np.concatenate([pin.Inertia.Random().toDynamicParameters() for _ in s.robot.body_names])
    assert np.max(np.abs(s.evaluate(th, thd, thdd) @ p2 - oracle(s, p2, th, thd, thdd))) < 1e-9


def test_joint_offset_enters_configuration_only(arm):
    tree, G, coords = arm
    off = RNG.normal(size=len(tree.joint_names)) * 0.3
    s = TransmissionStructure(tree, G, coords, offset=off)
    th, thd, thdd = random_states(len(coords))
    p = s.prior()
    assert np.max(np.abs(s.evaluate(th, thd, thdd) @ p - oracle(s, p, th, thd, thdd))) < 1e-9
    Q, V, A = s.pinocchio_state(th, thd, thdd)
    assert np.allclose(Q, th @ G.T + off) and np.allclose(V, thd @ G.T) and np.allclose(A, thdd @ G.T)


@pytest.mark.parametrize("smoothing", [0.0, 0.05])
def test_springs_rotor_inertia_motor_and_coupled_friction(arm, smoothing):
    tree, G, coords = arm
    s = TransmissionStructure(tree, G, coords, drives=drives(), coulomb_smoothing=smoothing)
    th, thd, thdd = random_states(len(coords))
    p = random_params(s)
    assert np.max(np.abs(s.evaluate(th, thd, thdd) @ p - oracle(s, p, th, thd, thdd, smoothing))) < 1e-9
    # each drive term alone, with the body block zeroed: a purely direct computation
    W = s.evaluate(th, thd, thdd)
    spring = s.drive_values(p)["q4spring"]
    k_only = np.zeros(s.n_params)
    k_only[s.joint_term_index("q4spring", "k")] = spring["k"]
    k_only[s.joint_term_index("q4spring", "k_rest")] = spring["k_rest"]
    expected = np.zeros((len(th), len(coords)))
    expected[:, 3] = spring["k"] * (th[:, 3] + 0.1) - spring["k_rest"]  # τ = k (s − s_rest), s = θ4 + s0
    assert np.max(np.abs(W @ k_only - expected)) < 1e-12
    inertia = np.zeros(s.n_params)
    inertia[s.joint_term_index("jaw", "fv")] = 0.7  # coupled viscous friction on the jaw
    g = 1.22 * np.eye(5)[4] - 0.83 * np.eye(5)[3]
    assert np.max(np.abs(W @ inertia - 0.7 * (thd @ g)[:, None] * g[None, :])) < 1e-12


def test_counterweight_body_equals_lumped_inertia(arm):
    """A counterweight as an extra body on a joint slaved to q2 gives the same torques as
    the same inertia appended rigidly to the pitch link (independent model)."""
    tree_cw, G_cw, coords = parallelogram_arm(counterweight=True)
    s_cw = TransmissionStructure(tree_cw, G_cw, coords)
    th, thd, thdd = random_states(len(coords))
    tau_cw = s_cw.evaluate(th, thd, thdd) @ s_cw.prior()
    # lumped model: the counterweight inertia moved into the pitch joint frame
    model = tree_cw.model.copy()
    cw = tree_cw.joint_id("counterweight")
    pitch = tree_cw.joint_id("pitch")
    lumped = pin.Model()
    for j in range(1, model.njoints):
        if j == cw:
            continue
        jm = model.joints[j].shortname()
        jmodel = pin.JointModelRZ() if jm == "JointModelRZ" else pin.JointModelPZ()
        lumped.addJoint(model.parents[j], jmodel, model.jointPlacements[j], model.names[j])
        lumped.appendBodyToJoint(j, model.inertias[j], pin.SE3.Identity())
    lumped.appendBodyToJoint(pitch, model.inertias[cw], pin.SE3(_rot("z", np.pi), np.zeros(3)))
    data = lumped.createData()
    G = np.delete(G_cw, tree_cw.joint_names.index("counterweight"), axis=0)
    ref = np.array([G.T @ pin.rnea(lumped, data, G @ th[i], G @ thd[i], G @ thdd[i]) for i in range(len(th))])
    assert np.max(np.abs(tau_cw - ref)) < 1e-9


def test_virtual_work_power_balance(arm):
    """τ_θ · θ̇ equals the tree's joint power τ_q · q̇ (Gᵀ map) plus the drive power f ṡ."""
    tree, G, coords = arm
    s = TransmissionStructure(tree, G, coords, drives=drives())
    th, thd, thdd = random_states(len(coords))
    p = random_params(s)
    tau = s.evaluate(th, thd, thdd) @ p
    Q, V, A = s.pinocchio_state(th, thd, thdd)
    m = tree.model.copy()
    for k, b in enumerate(s.robot.body_names):
        m.inertias[tree.joint_id(b)] = pin.Inertia.FromDynamicParameters(p[10 * k : 10 * k + 10])
    d = m.createData()
    tree_power = np.array([pin.rnea(m, d, Q[i], V[i], A[i]) @ V[i] for i in range(len(th))])
    drive_power = sum(
        drv.force(s.drive_values(p)[drv.name], th, thd, thdd) * (thd @ drv.g) for drv in s.drives
    )
    assert np.max(np.abs(np.einsum("nr,nr->n", tau, thd) - tree_power - drive_power)) < 1e-9


def test_rows_subset_and_interface(arm):
    tree, G, coords = arm
    s = TransmissionStructure(tree, G, coords, drives=drives(), rows=("q1", "q2", "m5"))
    th, thd, thdd = random_states(len(coords))
    p = random_params(s)
    assert s.n_rows == 3 and s.row_names == ["q1", "q2", "m5"]
    assert np.max(np.abs(s.evaluate(th, thd, thdd) @ p - oracle(s, p, th, thd, thdd))) < 1e-9
    assert s.robot.joint_names == coords and s.robot.nv == len(coords)
    assert s.labels[s.joint_term_index("m4", "inertia")] == "m4.inertia"
    with pytest.raises(RobotModelError):
        s.joint_term_index("m4", "k")
    traj = Trajectory(t=np.arange(3) * 0.01, q=th[:3, ::-1], v=thd[:3, ::-1], a=thdd[:3, ::-1], joint_names=coords[::-1])
    Q, _, _ = s.state(traj)
    assert np.allclose(Q, th[:3])  # reordered to the coordinates
    with pytest.raises(JointNameError):
        s.state(traj.with_(joint_names=("a", "b", "c", "d", "e")))
    with pytest.raises(RobotModelError):
        TransmissionStructure(tree, G[:, :3], coords)
    with pytest.raises(RobotModelError):
        TransmissionStructure(tree, G, coords, drives=[DriveTerm("x", [1.0, 0.0], ("fv",))])


def test_identify_and_compress_work_unchanged_and_recover_torques(arm):
    """compress()/identify() accept the structure as is: noiseless synthetic data from known
    parameters are reproduced to round-off, on a held-out trajectory too."""
    tree, G, coords = arm
    s = TransmissionStructure(tree, G, coords, drives=drives(), limits=(-np.ones(5), np.ones(5)))
    truth = random_params(s)

    def log(seed):
        r = np.random.default_rng(seed)
        f = FourierTrajectory(0.2, r.normal(size=(5, 4)) * 0.3, r.normal(size=(5, 4)) * 0.3, np.zeros(5), coords)
        tr = f.sample(100.0, 10.0)
        return tr.with_(tau=s.regressor(tr) @ truth)

    train, test = log(1), log(2)
    ne = compress(s, train.chunks(300))
    assert ne.A.shape == (5, s.n_params, s.n_params)
    res = identify(s, train)
    assert res.diagnostics["rank"] == base_parameters(s).rank < s.n_params
    pred = res.predict(test)
    assert np.max(np.abs(pred - test.tau)) < 1e-7 * np.abs(test.tau).max()


def test_structure_without_limits_on_a_tree_without_limits_identifies(arm):
    """Regression (docs/surgical-arm.md §2): joints added in code have Pinocchio's ±float-max "no
    limit"; the coordinate box overflowed the random states of base_parameters (OverflowError)."""
    tree, G, coords = arm
    lo, hi = tree.position_limits()
    assert np.all(np.isneginf(lo)) and np.all(np.isposinf(hi))  # "unlimited" is inf, as documented
    s = TransmissionStructure(tree, G, coords, drives=drives())
    clo, chi = s.robot.position_limits()
    assert np.allclose(clo, -np.pi) and np.allclose(chi, np.pi)
    f = FourierTrajectory(0.2, RNG.normal(size=(5, 4)) * 0.3, RNG.normal(size=(5, 4)) * 0.3, np.zeros(5), coords)
    tr = f.sample(100.0, 5.0)
    truth = random_params(s)
    res = identify(s, tr.with_(tau=s.regressor(tr) @ truth))
    assert np.max(np.abs(res.predict(tr) - s.regressor(tr) @ truth)) < 1e-7 * np.abs(s.regressor(tr) @ truth).max()
