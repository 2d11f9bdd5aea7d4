"""The simulated quadruped's whole-body controller (nominal model) and its references.

Joint references ``q*`` come from damped-Newton leg inverse kinematics of the planned feet
relative to the planned base (:class:`LegIK`), splined between every ``stride``-th sample.
Each control step (:class:`Controller`):

    v̇*_b = base PD on (p, R) towards the plan (world frame, mapped to LOCAL),
    τ_full = M(q) [v̇*_b; q̈*] + h(q, v),
    f = argmin ‖J_c,bᵀ f − τ_full,b‖² + λ‖f‖²   (stance feet, then f_z ≥ 0, |f_t| ≤ μ f_z),
    τ = τ_full,j − J_c,jᵀ f + Kp (q* − q) + Kd (q̇* − q̇),   clipped to the torque limit.

With no foot in stance the base rows use ``v̇_b = −M_bb⁻¹(M_bj q̈* + h_b)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from sensorless.errors import RobotModelError, SimulationError
from sensorless.robot import Robot
from .mujoco_scene import MujocoScene
from .quadruped_plans import PlanContext, Plan
from .quadruped_profiles import QuadrupedProfile

__all__ = ["Controller", "LegIK", "References", "references", "world_angular_velocity"]


# ---------------------------------------------------------------------------------------
class LegIK:
    """Damped Newton IK of foot-centre positions in the base frame (base at the identity)."""

    def __init__(self, robot: Robot, feet: Sequence[str]):
        self.model = robot.model
        self.data = self.model.createData()
        self.fids = [robot.frame_id(f) for f in feet]
        self.jq = np.array([robot.q_index(n) for n in robot.joint_names])
        self.jv = np.array([robot.v_index(n) for n in robot.joint_names])
        self.legs = []
        for fid in self.fids:
            joint = self.model.frames[fid].parentJoint
            sup = [j for j in self.model.supports[joint].tolist() if j > 1]
            self.legs.append(np.array([self.model.joints[j].idx_v for j in sup]))
        if len({leg.size for leg in self.legs}) != 1:
            raise RobotModelError("leg IK needs the same number of joints in every leg")
        self.legs_q = np.concatenate(
            [
                [
                    self.model.joints[j].idx_q
                    for j in self.model.supports[self.model.frames[f].parentJoint].tolist()
                    if j > 1
                ]
                for f in self.fids
            ]
        )
        self.q = pin.neutral(self.model)

    def positions(self, qj: np.ndarray) -> np.ndarray:
        q = self.q
        q[self.jq] = qj
        pin.framesForwardKinematics(self.model, self.data, q)
        return np.array([self.data.oMf[f].translation for f in self.fids])

    def solve(
        self, targets: np.ndarray, qj: np.ndarray, tol: float = 1e-7, max_iter: int = 50
    ) -> tuple[np.ndarray, float]:
        m, d, q = self.model, self.data, self.q
        q[self.jq] = qj
        err = np.inf
        eye = 1e-8 * np.eye(3)
        for _ in range(max_iter):
            pin.computeJointJacobians(m, d, q)
            pin.updateFramePlacements(m, d)
            e = targets - np.array([d.oMf[f].translation for f in self.fids])
            err = float(np.abs(e).max())
            if err < tol:
                break
            J = np.array(
                [
                    pin.getFrameJacobian(m, d, f, pin.LOCAL_WORLD_ALIGNED)[:3, leg]
                    for f, leg in zip(self.fids, self.legs)
                ]
            )
            JJt = J @ J.transpose(0, 2, 1) + eye
            dq = np.einsum("fji,fj->fi", J, np.linalg.solve(JJt, e[..., None])[..., 0])
            q[self.legs_q] += np.clip(dq, -0.3, 0.3).ravel()
        return q[self.jq].copy(), err


def world_angular_velocity(rpy: np.ndarray, drpy: np.ndarray) -> np.ndarray:
    """World angular velocity ω = J(rpy) ṙpy of R = Rz(y) Ry(p) Rx(r), batched (K, 3)
    (Pinocchio's ``rpy.computeRpyJacobian`` in the WORLD frame)."""
    J = np.array([pin.rpy.computeRpyJacobian(r, pin.WORLD) for r in rpy])
    return np.einsum("kij,kj->ki", J, drpy)


@dataclass
class References:
    p: np.ndarray
    R: np.ndarray
    v: np.ndarray
    a: np.ndarray
    w: np.ndarray
    dw: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    stance: np.ndarray
    ik_error: float


def references(ctx: PlanContext, plan: Plan, q_stand: np.ndarray, stride: int) -> References:
    from scipy.interpolate import CubicSpline

    t = ctx.t
    dt = t[1] - t[0]
    R = Rotation.from_euler("xyz", plan.base_rpy).as_matrix()  # Rz(yaw) Ry(pitch) Rx(roll)
    v = np.gradient(plan.base_pos, dt, axis=0, edge_order=2)
    a = np.gradient(v, dt, axis=0, edge_order=2)
    drpy = np.gradient(plan.base_rpy, dt, axis=0, edge_order=2)
    w = world_angular_velocity(plan.base_rpy, drpy)
    dw = np.gradient(w, dt, axis=0, edge_order=2)
    ik = LegIK(ctx.robot, ctx.profile.feet)
    idx = np.unique(np.r_[np.arange(0, t.size, stride), t.size - 1])
    qs = np.empty((idx.size, q_stand.size))
    qj = q_stand.copy()
    worst, t_worst = 0.0, 0.0
    for n, k in enumerate(idx):
        targets = (plan.feet[k] - plan.base_pos[k]) @ R[k]  # Rᵀ (p_foot − p_base), row-wise
        qj, err = ik.solve(targets, qj)
        if err > worst:
            worst, t_worst = err, t[k] - ctx.t0
        qs[n] = qj
    if worst > 1e-4:
        raise SimulationError(
            f"the scenario plan asks for unreachable foot positions (IK error {worst:.3g} m at t = {t_worst:.2f} s); "
            "reduce its speed, step length or amplitude"
        )
    if stride == 1:
        q = qs
        dq = np.gradient(q, dt, axis=0, edge_order=2)
        ddq = np.gradient(dq, dt, axis=0, edge_order=2)
    else:
        sp = CubicSpline(t[idx], qs, axis=0)
        q, dq, ddq = sp(t), sp(t, 1), sp(t, 2)
    return References(plan.base_pos, R, v, a, w, dw, q, dq, ddq, plan.stance, worst)


class Controller:
    """Inverse-dynamics tracking of the plan with stance-force distribution (nominal model)."""

    def __init__(self, robot: Robot, scene: MujocoScene, prof: QuadrupedProfile, ref: References):
        self.model = robot.model.copy()
        self.data = self.model.createData()
        self.fids = [robot.frame_id(f) for f in prof.feet]
        nq, nv = self.model.nq, self.model.nv
        jq = np.array([robot.q_index(n) for n in robot.joint_names])
        jv = np.array([robot.v_index(n) for n in robot.joint_names])
        contiguous = (
            np.array_equal(jq, np.arange(7, nq))
            and np.array_equal(jv, np.arange(6, nv))
            and np.array_equal(scene.qpos_adr, np.arange(7, nq))
            and np.array_equal(scene.dof_adr, np.arange(6, nv))
        )
        if not contiguous:
            raise RobotModelError("the quadruped controller needs 1-DoF joints below the free flyer, in model order")
        self.act_cols = np.array([robot.joint_names.index(j) for j in robot.actuated_joints])
        self.lo, self.hi = -scene.torque_limit, scene.torque_limit
        self.prof = prof
        self.ref = ref
        self.base = scene.base_body
        self.q = pin.neutral(self.model)
        self.v = np.zeros(nv)
        self.acc = np.zeros(nv)
        self.mu = prof.friction_coefficient * 0.8
        self.reg = 1e-6 * np.eye(6)

    def __call__(self, k: int, d: mujoco.MjData) -> np.ndarray:
        ref, prof = self.ref, self.prof
        q, v, acc = self.q, self.v, self.acc
        qpos, qvel = d.qpos, d.qvel
        q[:3] = qpos[:3]
        q[3:6] = qpos[4:7]
        q[6] = qpos[3]
        q[7:] = qpos[7:]
        R = d.xmat[self.base].reshape(3, 3)  # base orientation (kinematics of mj_step1)
        vw = qvel[:3]
        wl = qvel[3:6]
        vl = vw @ R
        v[:3] = vl
        v[3:6] = wl
        v[6:] = qvel[6:]
        model, data = self.model, self.data
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        M, h = data.M, data.nle
        # base: PD towards the plan in the world frame, mapped to Pinocchio's LOCAL derivative
        e_rot = pin.log3(ref.R[k] @ R.T)
        kp, kd = prof.gains.base_kp, prof.gains.base_kd
        a_w = ref.a[k] + kp * (ref.p[k] - q[:3]) + kd * (ref.v[k] - vw)
        al_w = ref.dw[k] + kp * e_rot + kd * (ref.w[k] - R @ wl)
        wx, wy, wz = wl
        vx, vy, vz = vl
        acc[:3] = a_w @ R - (wy * vz - wz * vy, wz * vx - wx * vz, wx * vy - wy * vx)
        acc[3:6] = al_w @ R
        acc[6:] = ref.ddq[k]
        stance = ref.stance[k]
        if stance.any():
            tau_full = M @ acc + h
            Jc = np.concatenate(
                [
                    pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
                    for fid, s in zip(self.fids, stance)
                    if s
                ]
            )
            A = Jc[:, :6]
            G = A.T @ A
            G += self.reg * (np.trace(G) + 1e-6)
            f = (A @ np.linalg.solve(G, tau_full[:6])).reshape(-1, 3)
            fz = np.maximum(f[:, 2], 0.0)
            n = np.sqrt(f[:, 0] ** 2 + f[:, 1] ** 2)
            scale = np.minimum(1.0, self.mu * fz / (n + 1e-12))
            f[:, 0] *= scale
            f[:, 1] *= scale
            f[:, 2] = fz
            tau_j = tau_full[6:] - f.ravel() @ Jc[:, 6:]
        else:  # flight: base acceleration that the joint motion implies
            ab = -np.linalg.solve(M[:6, :6], M[:6, 6:] @ acc[6:] + h[:6])
            tau_j = M[6:, :6] @ ab + M[6:, 6:] @ acc[6:] + h[6:]
        tau_j += prof.gains.kp * (ref.q[k] - q[7:]) + prof.gains.kd * (ref.dq[k] - v[6:])
        return np.minimum(np.maximum(tau_j[self.act_cols], self.lo), self.hi)
