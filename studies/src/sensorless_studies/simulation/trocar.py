"""Simulated trocar interaction for a PSM-like arm, with ground-truth forces.

Physics (true arm, joint space)::

    M(q) q̈ + h(q, q̇) + τ_f(q̇) + o = τ_cmd + J_wᵀ F_wall + J_tᵀ F_tip (+ roll-seal torque)

* ``τ_f = fv q̇ + fc tanh(q̇/ε)`` joint friction, ``o`` constant offsets (:class:`ArmTruth`).
* **Body wall** (:class:`BodyWall`): a horizontal plane ``depth`` below the RCM with the
  incision at ``anchor``. The shaft crosses the plane at point p; its lateral displacement
  d = p − anchor loads the wall: ``F_lat = −K d − k₃|d|² d − D ṗ_xy`` with K = diag(k_x, k_y),
  k_x ≠ k_y. Along the shaft a seal friction ``−(b v_ax + (f₀ + μ|F_el|) tanh(v_ax/ε)) s``
  acts (its Coulomb level grows with the lateral load). The wrench is applied to the
  insertion body at p: τ = J_pᵀ F with J_p the Jacobian of that material point.
* **Tip contact** (:class:`SphereObject`): penalty contact of the jaw tip with a sphere,
  ``F = max(0, kδ − c δ̇_n) n − μ F_n v_t / √(|v_t|² + ε²)``.
* **Controller**: computed torque on the *nominal* model at 1 kHz,
  ``τ_cmd = rnea_nom(q, q̇, q̈_d + K_p e + K_d ė)``, zero-order hold.
* **Integrator**: forward dynamics from Pinocchio (``computeAllTerms``: M, h, Jacobians),
  linearly implicit Euler in the stiff terms (friction, wall, contact)::

      (M + Δt D + Δt² K) Δq̇ = Δt (f − Δt K q̇),   q̇⁺ = q̇ + Δq̇,  q⁺ = q + Δt q̇⁺

  with D = −∂f/∂q̇, K = −∂f/∂q of those terms (with D = K = 0 this is ``pin.aba``'s q̈).
  The logged ground-truth forces are the ones effectively applied over the step.

Logs are what a user has: noisy q, q̇ and measured (= commanded, current-controlled)
torque at ``1/(dt·log_every)`` Hz; ground truth goes in ``Trajectory.extras``:
``f_tip`` (N, 3): force the jaw tip exerts on the tissue (world axes, at ``tool_tip``; what
a tip force sensor would read), ``f_wall`` (N, 3): force of the shaft on the body wall,
``tau_wall`` = J_wᵀ f_wall (+ seal), ``tau_contact`` = J_tᵀ f_tip (N, n), so that
τ_cmd = τ_model + τ_wall + τ_contact; also ``tau_cmd`` (noise-free), ``q_true``, ``v_true``,
``a_true``, ``q_des`` and ``in_contact``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Sequence

import numpy as np
import pinocchio as pin

from sensorless.data.trajectory import Trajectory
from sensorless.robot import Robot
from .surgical_arm import TIP_FRAME, build_surgical_arm
from .trocar_motions import AMAX, VMAX, WORKSPACES, DesiredMotion, multisine_motion, probing_motion

__all__ = [
    "ArmTruth",
    "BodyWall",
    "SimulationSettings",
    "SphereObject",
    "SurgicalDatasets",
    "TrocarSimulator",
    "make_datasets",
    "payload_log",
    "perturbed_arm",
]


def _skew(x: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


# ---- the world ------------------------------------------------------------------
@dataclass
class BodyWall:
    """Compliant, anisotropic body wall crossed by the shaft (see module docstring)."""

    depth: float = 0.04  # wall plane below the RCM [m]
    anchor: tuple[float, float] = (0.004, -0.003)  # incision centre (x, y) [m]
    kx: float = 400.0  # lateral stiffness [N/m]
    ky: float = 700.0
    k3: float = 5.0e5  # cubic stiffening [N/m³]
    damping: tuple[float, float] = (5.0, 5.0)  # lateral damping [N s/m]
    axial_viscous: float = 3.0  # [N s/m]
    axial_coulomb: float = 0.5  # [N]
    axial_mu: float = 0.2  # seal friction per newton of lateral load
    axial_eps: float = 0.005  # [m/s]
    roll_viscous: float = 0.002  # [N m s/rad]
    roll_coulomb: float = 0.004  # [N m]
    roll_eps: float = 0.05  # [rad/s]

    def force(self, p: np.ndarray, vp: np.ndarray, s: np.ndarray):
        """Force on the shaft at p (world), its stiffness and damping (3×3, world)."""
        d = p[:2] - np.asarray(self.anchor)
        r2 = float(d @ d)
        kxy = np.array([self.kx, self.ky])
        f_el = -(kxy * d + self.k3 * r2 * d)
        f_lat = f_el - np.asarray(self.damping) * vp[:2]
        v_ax = float(vp @ s)
        fc = self.axial_coulomb + self.axial_mu * float(np.hypot(*f_el))
        th = np.tanh(v_ax / self.axial_eps)
        F = np.array([f_lat[0], f_lat[1], 0.0]) - (self.axial_viscous * v_ax + fc * th) * s
        K = np.diag([self.kx + 3 * self.k3 * r2, self.ky + 3 * self.k3 * r2, 0.0])
        D = np.diag([self.damping[0], self.damping[1], 0.0])
        D += (self.axial_viscous + fc / self.axial_eps * (1 - th * th)) * np.outer(s, s)
        return F, K, D

    def roll_torque(self, w: float) -> tuple[float, float]:
        th = np.tanh(w / self.roll_eps)
        return -(self.roll_viscous * w + self.roll_coulomb * th), self.roll_viscous + self.roll_coulomb / self.roll_eps * (1 - th * th)


@dataclass
class SphereObject:
    """A stiff tissue-like sphere the jaw tip can press on (penalty contact + friction)."""

    centre: tuple[float, float, float] = (0.0, 0.0, -0.25)
    radius: float = 0.08
    stiffness: float = 1500.0  # [N/m]
    damping: float = 10.0  # [N s/m]
    mu: float = 0.3
    eps: float = 0.005  # [m/s]

    def force(self, p: np.ndarray, v: np.ndarray):
        """Contact force on the tip (world), stiffness, damping; None when not touching."""
        r = p - np.asarray(self.centre)
        dist = float(np.linalg.norm(r))
        pen = self.radius - dist
        if pen <= 0:
            return None
        n = r / dist
        vn = float(v @ n)
        fn = max(0.0, self.stiffness * pen - self.damping * vn)
        vt = v - vn * n
        g = np.sqrt(vt @ vt + self.eps**2)
        F = fn * n - self.mu * fn * vt / g
        nn = np.outer(n, n)
        K = self.stiffness * nn if fn > 0 else np.zeros((3, 3))
        D = (self.damping * nn + self.mu * fn / g * (np.eye(3) - nn)) if fn > 0 else np.zeros((3, 3))
        return F, K, D

    def hit_distance(self, u: np.ndarray) -> float:
        """Distance along unit ray u from the RCM (origin) to the sphere surface (nan: miss)."""
        c = np.asarray(self.centre)
        b = float(u @ c)
        disc = b * b - (c @ c - self.radius**2)
        return b - np.sqrt(disc) if disc >= 0 else float("nan")


@dataclass
class ArmTruth:
    """The 'real' arm: true inertias/armature in ``robot`` plus joint friction and offsets."""

    robot: Robot
    fv: np.ndarray
    fc: np.ndarray
    offset: np.ndarray
    coulomb_eps: float = 0.01

    def friction(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Friction torque τ_f(q̇) and its derivative (diagonal)."""
        th = np.tanh(v / self.coulomb_eps)
        return self.fv * v + self.fc * th, self.fv + self.fc / self.coulomb_eps * (1 - th * th)

    def parameters(self, joint_terms=("fv", "fc", "offset", "armature")) -> np.ndarray:
        """Standard parameters in the layout of :class:`~sensorless.regressor.ModelStructure`."""
        arm = self.robot.armature
        vals = {"fv": self.fv, "fc": self.fc, "offset": self.offset, "armature": arm}
        per = np.stack([vals[t] for t in joint_terms], axis=1).ravel() if joint_terms else np.zeros(0)
        return np.concatenate([self.robot.inertial_parameters(), per])

    def with_payload(self, inertia: pin.Inertia, frame: str = TIP_FRAME) -> ArmTruth:
        """A copy carrying a rigid payload (inertia expressed in ``frame``) fixed to that frame."""
        model = self.robot.model.copy()
        f = model.frames[self.robot.frame_id(frame)]
        model.inertias[f.parentJoint] = model.inertias[f.parentJoint] + f.placement.act(inertia)
        r = Robot(model, name=self.robot.name + "_payload", source=self.robot.source, actuated_joints=self.robot.actuated_joints)
        return replace(self, robot=r)


def perturbed_arm(nominal: Robot, rng: np.random.Generator | int = 0, mass_scale: float = 0.15, com_shift: float = 0.01) -> ArmTruth:
    """A true arm near the nominal one: masses ×U(1±mass_scale), CoM shifts, friction, offsets."""
    rng = np.random.default_rng(rng)
    model = nominal.model.copy()
    for j in range(1, model.njoints):
        I = model.inertias[j]
        s = 1.0 + mass_scale * rng.uniform(-1, 1)
        shift = com_shift * (1.0 if I.mass > 0.05 else 0.2) * rng.uniform(-1, 1, 3)
        model.inertias[j] = pin.Inertia(I.mass * s, I.lever + shift, I.inertia * s)
    model.armature[:] = np.asarray(nominal.model.armature) * rng.uniform(0.8, 1.2, nominal.nv)
    true = Robot(model, name=nominal.name + "_truth", source=nominal.source, actuated_joints=nominal.actuated_joints)
    fv = np.array([0.05, 0.05, 2.0, 0.002, 0.001, 0.001]) * rng.uniform(0.7, 1.3, 6)
    fc = np.array([0.06, 0.05, 0.4, 0.004, 0.003, 0.003]) * rng.uniform(0.7, 1.3, 6)
    off = np.array([0.03, 0.03, 0.2, 0.002, 0.001, 0.001]) * rng.uniform(-1, 1, 6)
    return ArmTruth(true, fv, fc, off)


# ---- simulator ---------------------------------------------------------------------
@dataclass
class SimulationSettings:
    dt: float = 1e-3  # control and integration period [s]
    log_every: int = 5  # log at 1/(dt·log_every) Hz (200 Hz)
    omega: tuple[float, ...] = (30.0, 30.0, 30.0, 80.0, 80.0, 80.0)  # computed-torque bandwidth per joint [rad/s]
    zeta: float = 1.0
    torque_noise: tuple[float, ...] = (0.01, 0.01, 0.05, 0.001, 5e-4, 5e-4)  # N·m (N)
    velocity_noise: float = 0.003  # rad/s (m/s)
    position_noise: float = 2e-5  # rad (m)


class TrocarSimulator:
    """Computed-torque tracking of a desired motion on the true arm, with optional body wall
    and tip contact (see module docstring). ``nominal`` is the controller's (CAD) model."""

    def __init__(
        self,
        nominal: Robot,
        truth: ArmTruth,
        wall: BodyWall | None = None,
        objects: Sequence[SphereObject] = (),
        settings: SimulationSettings | None = None,
    ) -> None:
        self.nominal, self.truth = nominal, truth
        self.wall = wall or BodyWall()
        self.objects = list(objects)
        self.settings = settings or SimulationSettings()

    def run(self, motion: DesiredMotion, *, trocar: bool, contact: bool, rng: np.random.Generator | int = 0, name: str = "sim") -> Trajectory:
        rng = np.random.default_rng(rng)
        st = self.settings
        model, data = self.truth.robot.model, self.truth.robot.model.createData()
        nom, ndata = self.nominal.model, self.nominal.model.createData()
        n, dt = model.nv, st.dt
        omega = np.asarray(st.omega, dtype=float)
        kp, kd = omega**2, 2 * st.zeta * omega
        ins = model.getJointId("insertion")
        roll = model.joints[model.getJointId("roll")].idx_v
        tip = model.getFrameId(TIP_FRAME)
        LWA = pin.LOCAL_WORLD_ALIGNED
        wall, objects = self.wall, self.objects if contact else []
        steps = len(motion)
        n_log = (steps + st.log_every - 1) // st.log_every
        log = {k: np.zeros((n_log, w)) for k, w in (("q", n), ("v", n), ("a", n), ("tau", n), ("f_tip", 3), ("f_wall", 3),
                                                     ("tau_wall", n), ("tau_contact", n), ("qd", n), ("contact", 1))}
        q, v = motion.q[0].copy(), motion.v[0].copy()
        zero3 = np.zeros(3)
        for k in range(steps):
            e, ed = motion.q[k] - q, motion.v[k] - v
            tau = pin.rnea(nom, ndata, q, v, motion.a[k] + kp * e + kd * ed).copy()
            pin.computeAllTerms(model, data, q, v)
            M = np.triu(data.M) + np.triu(data.M, 1).T
            tf, dtf = self.truth.friction(v)
            f = tau - data.nle - tf - self.truth.offset
            D = np.diag(dtf)
            K = np.zeros((n, n))
            Jw = Jt = None
            if trocar:
                oMi = data.oMi[ins]
                o, s = oMi.translation, oMi.rotation[:, 2]
                p = o + (-wall.depth - o[2]) / s[2] * s
                Jj = pin.getJointJacobian(model, data, ins, LWA)
                Jw = Jj[:3] - _skew(p - o) @ Jj[3:]
                Fw, Kw, Dw = wall.force(p, Jw @ v, s)
                tr, dtr = wall.roll_torque(v[roll])
                f += Jw.T @ Fw
                f[roll] += tr
                K += Jw.T @ Kw @ Jw
                D += Jw.T @ Dw @ Jw
                D[roll, roll] += dtr
            Fc, Kc, Dc = zero3, None, None
            if objects:
                pin.updateFramePlacement(model, data, tip)
                pt = data.oMf[tip].translation
                Jt = pin.getFrameJacobian(model, data, tip, LWA)[:3]
                vt = Jt @ v
                for obj in objects:
                    res = obj.force(pt, vt)
                    if res is not None:
                        Fc, Kc, Dc = res
                        f += Jt.T @ Fc
                        K += Jt.T @ Kc @ Jt
                        D += Jt.T @ Dc @ Jt
                        break
            dv = np.linalg.solve(M + dt * D + dt * dt * K, dt * (f - dt * K @ v))
            v_new = v + dv
            if k % st.log_every == 0:
                i = k // st.log_every
                log["q"][i], log["v"][i], log["a"][i], log["tau"][i], log["qd"][i] = q, v, dv / dt, tau, motion.q[k]
                # forces effectively applied over the step (implicit terms included), logged as
                # the robot's action on the environment: τ_meas = τ_model + τ_wall + τ_contact
                if Jw is not None:
                    Fw_eff = -(Fw - Kw @ (Jw @ v_new) * dt - Dw @ (Jw @ dv))
                    log["f_wall"][i] = Fw_eff
                    log["tau_wall"][i] = Jw.T @ Fw_eff
                    log["tau_wall"][i, roll] -= tr - dtr * dv[roll]
                if Kc is not None:
                    Fc_eff = -(Fc - Kc @ (Jt @ v_new) * dt - Dc @ (Jt @ dv))
                    log["f_tip"][i], log["tau_contact"][i], log["contact"][i] = Fc_eff, Jt.T @ Fc_eff, 1.0
            v = v_new
            q = q + dt * v
        t = motion.t[:: st.log_every][:n_log]
        noise_tau = rng.normal(size=(n_log, n)) * np.asarray(st.torque_noise)
        return Trajectory(
            t=t,
            q=log["q"] + rng.normal(size=(n_log, n)) * st.position_noise,
            v=log["v"] + rng.normal(size=(n_log, n)) * st.velocity_noise,
            tau=log["tau"] + noise_tau,
            joint_names=self.nominal.joint_names,
            extras={
                "f_tip": log["f_tip"], "f_wall": log["f_wall"], "tau_wall": log["tau_wall"],
                "tau_contact": log["tau_contact"], "tau_cmd": log["tau"], "q_true": log["q"],
                "v_true": log["v"], "a_true": log["a"], "q_des": log["qd"], "in_contact": log["contact"][:, 0],
            },
            units={"f_tip": "N, tip on tissue, world axes, at tool_tip", "f_wall": "N, shaft on wall, world axes, at the wall crossing"},
            source=f"<sim {self.nominal.name} {name}>",
        )


# ---- datasets ---------------------------------------------------------------------
@dataclass
class SurgicalDatasets:
    """Logs of one simulated setup (nominal robot + true arm + wall + tissue sphere)."""

    robot: Robot
    truth: ArmTruth
    wall: BodyWall
    sphere: SphereObject
    settings: dict
    free_space: Trajectory  # free-space excitation over the whole workspace (identification)
    split_train: Trajectory  # free space, workspace A
    split_test: Trajectory  # free space, workspace B (disjoint from A in yaw and pitch)
    trocar_train: list[Trajectory]  # in the trocar, no tip contact (multisine + air palpation)
    trocar_test: list[Trajectory]  # same, other seed
    trocar_contact: Trajectory  # in the trocar, palpating the sphere (ground-truth f_tip)
    simulator: TrocarSimulator = field(repr=False, default=None)  # type: ignore[assignment]


DURATIONS = {
    "full": {"free_space": 120.0, "split": 60.0, "trocar_multisine": 120.0, "trocar_probe": 240.0, "trocar_test": 40.0, "contact": 60.0},
    "quick": {"free_space": 60.0, "split": 30.0, "trocar_multisine": 40.0, "trocar_probe": 120.0, "trocar_test": 20.0, "contact": 30.0},
}


def make_datasets(seed: int = 0, *, quick: bool = False, durations: dict | None = None,
                  settings: SimulationSettings | None = None) -> SurgicalDatasets:
    """Simulate the study's logs (all seeded from ``seed``). Durations in seconds per log."""
    dur = dict(DURATIONS["quick" if quick else "full"], **(durations or {}))
    ss = np.random.SeedSequence(seed)
    r = [np.random.default_rng(s) for s in ss.spawn(16)]
    robot = build_surgical_arm()
    truth = perturbed_arm(robot, r[0])
    wall, sphere = BodyWall(), SphereObject()
    sim = TrocarSimulator(robot, truth, wall, [sphere], settings)
    dt = sim.settings.dt
    W = WORKSPACES
    free = sim.run(multisine_motion(W["full"], dur["free_space"], dt=dt, rng=r[1]), trocar=False, contact=False, rng=r[2], name="free_space")
    a = sim.run(multisine_motion(W["split_train"], dur["split"], dt=dt, rng=r[3]), trocar=False, contact=False, rng=r[4], name="split_train")
    b = sim.run(multisine_motion(W["split_test"], dur["split"], dt=dt, rng=r[5]), trocar=False, contact=False, rng=r[6], name="split_test")
    tv, ta = VMAX * 0.6, AMAX * 0.6
    tr_ms = sim.run(multisine_motion(W["trocar"], dur["trocar_multisine"], dt=dt, rng=r[7], vmax=tv, amax=ta),
                    trocar=True, contact=False, rng=r[8], name="trocar_multisine")
    tr_pr = sim.run(probing_motion(sphere, dur["trocar_probe"], dt=dt, rng=r[9]), trocar=True, contact=False, rng=r[10], name="trocar_air_palpation")
    te_ms = sim.run(multisine_motion(W["trocar"], dur["trocar_test"], dt=dt, rng=r[11], vmax=tv, amax=ta),
                    trocar=True, contact=False, rng=r[12], name="trocar_test_multisine")
    te_pr = sim.run(probing_motion(sphere, dur["trocar_test"], dt=dt, rng=r[13]), trocar=True, contact=False, rng=r[14], name="trocar_test_air_palpation")
    con = sim.run(probing_motion(sphere, dur["contact"], dt=dt, rng=r[15]), trocar=True, contact=True, rng=ss.spawn(1)[0], name="trocar_contact")
    info = {
        "seed": seed, "quick": quick, "durations_s": dur, "log_rate_hz": 1.0 / (dt * sim.settings.log_every),
        "control_rate_hz": 1.0 / dt, "workspaces": {k: [list(x) for x in v] for k, v in W.items()},
        "wall": asdict(wall), "sphere": asdict(sphere), "simulation": asdict(sim.settings),
        "truth": {"fv": truth.fv.tolist(), "fc": truth.fc.tolist(), "offset": truth.offset.tolist(),
                  "armature": truth.robot.armature.tolist(), "coulomb_eps": truth.coulomb_eps},
        "engine": "Pinocchio computeAllTerms + linearly implicit Euler (1 kHz), computed-torque control on the nominal model",
    }
    return SurgicalDatasets(robot, truth, wall, sphere, info, free, a, b, [tr_ms, tr_pr], [te_ms, te_pr], con, sim)


def payload_log(
    datasets: SurgicalDatasets,
    payload: pin.Inertia,
    *,
    frame: str = TIP_FRAME,
    duration: float = 40.0,
    seed: int = 0,
    box: Sequence[tuple[float, float]] | None = None,
) -> Trajectory:
    """Free-space log of the true arm carrying ``payload`` (inertia expressed in ``frame``)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 7]))
    truth = datasets.truth.with_payload(payload, frame)
    sim = TrocarSimulator(datasets.robot, truth, settings=datasets.simulator.settings)
    motion = multisine_motion(box or WORKSPACES["full"], duration, dt=sim.settings.dt, rng=rng)
    return sim.run(motion, trocar=False, contact=False, rng=rng, name="payload")
