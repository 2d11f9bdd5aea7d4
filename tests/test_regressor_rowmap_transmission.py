"""Transmission row map: W π equals Gᵀ RNEA(Gθ + q₀, Gθ̇, Gθ̈) plus the drive terms Σ g_d f_d.

Oracle: RNEA of the tree with inertias from random π at the joint values of random
coordinates, mapped by Gᵀ by hand, plus drive forces computed directly, to 1e-9.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from sensorless.regressor.drive_terms import DriveTerm
from sensorless.regressor.rowmap import RowMap, TransmissionRows
from sensorless.regressor.transmission import TransmissionStructure, add_body_joint, coupling_matrix
from sensorless.robot import Robot


def _coupled_tree():
    """yaw, pitch, a parallelogram link slaved to −pitch, and a 2-motor coupled wrist."""
    m = pin.Model()
    j1 = add_body_joint(m, 0, "yaw", pin.SE3(pin.utils.rotate("x", np.pi / 2), np.zeros(3)))
    j2 = add_body_joint(m, j1, "pitch", pin.SE3(pin.utils.rotate("x", -np.pi / 2), np.array([0.1, 0, 0])))
    j3 = add_body_joint(m, j2, "par", pin.SE3(np.eye(3), np.array([0.3, 0.02, 0])))
    j4 = add_body_joint(m, j3, "wrist_a", pin.SE3(pin.utils.rotate("x", np.pi / 2), np.array([0, 0, 0.2])))
    add_body_joint(m, j4, "wrist_b", pin.SE3(pin.utils.rotate("x", -np.pi / 2), np.array([0.01, 0, 0])),
                   kind="prismatic")
    for j in range(1, m.njoints):
        m.inertias[j] = pin.Inertia.Random()
    tree = Robot(m, name="coupled")
    coords = ("q1", "q2", "m3", "m4")
    rules = {"yaw": {"q1": 1.0}, "pitch": {"q2": 1.0}, "par": {"q2": -1.0},
             "wrist_a": {"m3": 1.1}, "wrist_b": {"m3": -0.7, "m4": 0.9}}
    return tree, coupling_matrix(tree.joint_names, coords, rules), coords


def test_transmission_rows_equal_gt_rnea_plus_drive_terms():
    rng = np.random.default_rng(21)
    tree, G, coords = _coupled_tree()
    e = np.eye(len(coords))
    drives = [DriveTerm("q1", e[0], ("fv", "fc", "offset")), DriveTerm("m3", e[2], ("fv", "inertia", "spring"), s0=0.2),
              DriveTerm("jaw", 0.9 * e[3] - 0.7 * e[2], ("fv", "fc"))]
    offset = rng.normal(size=len(tree.joint_names)) * 0.1
    s = TransmissionStructure(tree, G, coords, offset=offset, drives=drives, bodies=tree.body_names[1:],
                              rows=("q1", "m3", "m4"))
    rm = s.row_map
    assert isinstance(rm, RowMap) and isinstance(rm, TransmissionRows)
    assert not rm.selects_rows and not rm.per_sample and rm.row_names == ["q1", "m3", "m4"] == s.row_names
    n = 30
    th, thd, thdd = rng.normal(size=(n, 4)), rng.normal(size=(n, 4)) * 2, rng.normal(size=(n, 4)) * 5
    pi = np.concatenate([np.concatenate([pin.Inertia.Random().toDynamicParameters() for _ in s.robot.body_names]),
                         rng.normal(size=s.n_params - s.n_body_params)])
    model = tree.model.copy()
    model.inertias[1] = pin.Inertia.Zero()  # the first body is left out of `bodies`: massless
    for k, b in enumerate(s.robot.body_names):
        model.inertias[tree.joint_id(b)] = pin.Inertia.FromDynamicParameters(pi[10 * k : 10 * k + 10])
    data = model.createData()
    q, v, a = th @ G.T + offset, thd @ G.T, thdd @ G.T
    tau_q = np.array([pin.rnea(model, data, q[i], v[i], a[i]) for i in range(n)])
    tau_th = tau_q @ G  # Gᵀ τ_q per sample
    for d, vals in s.drive_values(pi).items():
        g = next(x.g for x in drives if x.name == d)
        s0 = next(x.s0 for x in drives if x.name == d)
        sv, sd, sdd = th @ g + s0, thd @ g, thdd @ g
        f = (vals.get("fv", 0) * sd + vals.get("fc", 0) * np.sign(sd) + vals.get("offset", 0)
             + vals.get("inertia", 0) * sdd + vals.get("k", 0) * sv - vals.get("k_rest", 0))
        tau_th += f[:, None] * g[None, :]
    keep = [coords.index(c) for c in ("q1", "m3", "m4")]
    np.testing.assert_allclose(s.evaluate(th, thd, thdd) @ pi, tau_th[:, keep], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(rm.apply(tau_q), (tau_q @ G)[:, keep], rtol=1e-12, atol=1e-12)
    # the coordinate robot shares the actuation interface and names its transmission
    assert s.robot.transmission_matrix is G or np.array_equal(s.robot.transmission_matrix, G)
    assert tree.transmission_matrix is None
    np.testing.assert_array_equal(s.robot.selection, np.eye(4)[keep])


def test_transmission_is_a_model_structure_with_a_state_map_and_a_row_map():
    """Issue 15: the transmission composes (coordinate robot + q = Gθ + q₀ + Gᵀ rows + drive
    block) instead of overriding; ModelStructure's blocks give Gᵀ Y(Gθ + q₀, …)[:, bodies] and
    the drive columns, and compress folds them to the dense normal equations."""
    from sensorless.data import Trajectory
    from sensorless.regressor import ModelStructure, NormalEquations, compress

    overrides = {n for n in vars(TransmissionStructure) if n in dir(ModelStructure) and not n.startswith("__")}
    assert overrides == {"pinocchio_state", "settings"}
    rng = np.random.default_rng(22)
    tree, G, coords = _coupled_tree()
    e = np.eye(len(coords))
    drives = [DriveTerm("q2", e[1], ("fv", "fc", "spring")), DriveTerm("jaw", e[3] - 0.5 * e[2], ("fv", "inertia"))]
    offset = rng.normal(size=len(tree.joint_names)) * 0.1
    s = TransmissionStructure(tree, G, coords, offset=offset, drives=drives, bodies=tree.body_names[1:],
                              rows=("q1", "q2", "m4"), coulomb_smoothing=0.05)
    assert s.n_block_params == s.n_params == s.n_body_params + 6 and s.n_drive_params == 6  # fv fc k k_rest | fv inertia
    assert not (s.row_map.per_sample or s.row_map.projected or s.row_map.measured_wrench or s.measured_wrench)
    n = 40
    th, thd, thdd = rng.normal(size=(n, 4)), rng.normal(size=(n, 4)) * 2, rng.normal(size=(n, 4)) * 5
    W = s.evaluate(th, thd, thdd)
    # body block: Pinocchio's regressor at the tree state, bodies' columns, Gᵀ on the kept rows
    q, v, a = th @ G.T + offset, thd @ G.T, thdd @ G.T
    cols = np.concatenate([np.arange(10 * i, 10 * i + 10) for i in (tree.body_names.index(b) for b in s.robot.body_names)])
    keep = [coords.index(c) for c in ("q1", "q2", "m4")]
    Y = np.array([pin.computeJointTorqueRegressor(tree.model, tree.data, q[i], v[i], a[i])[:, cols] for i in range(n)])
    np.testing.assert_allclose(s.body_regressor(th, thd, thdd), np.einsum("jr,njp->nrp", G[:, keep], Y), atol=1e-10)
    np.testing.assert_array_equal(s.block_regressor(th, thd, thdd), W)
    # drive block: column p of drive d is g_d f_{d,p}
    for d, sl in zip(drives, s.drive_slices()):
        F = d.features(th, thd, thdd, 0.05)
        np.testing.assert_allclose(W[:, :, sl], d.g[keep][None, :, None] * F[:, None, :], atol=1e-12)
        assert s.labels[sl] == d.labels and s.joint_term_index(d.name, d.param_names[-1]) == sl.stop - 1
    # the chunked fold equals the dense normal equations of (W, target)
    tau = W @ rng.normal(size=s.n_params)
    tau_all = np.zeros((n, 4))
    tau_all[:, keep] = tau
    tr = Trajectory(t=np.arange(n) * 0.01, q=th, v=thd, a=thdd, tau=tau_all, joint_names=coords, source="<random>")
    np.testing.assert_array_equal(s.target(tr), tau)
    dense = NormalEquations.zeros(s.n_rows, s.n_params)
    dense.add(W, tau)
    ne = compress(s, tr, chunk=16, overlap=False)
    scale = np.abs(dense.A).max()
    np.testing.assert_allclose(ne.A, dense.A, atol=1e-12 * scale)
    np.testing.assert_allclose(ne.b, dense.b, atol=1e-12 * np.abs(dense.b).max())
