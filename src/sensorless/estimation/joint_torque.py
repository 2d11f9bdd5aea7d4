"""Joint torques from 6-axis F/T sensors, an IMU and encoders (no joint-torque sensors).

Each F/T sensor splits the body that carries it into a proximal part and a distal part
(e.g. ankle link | foot sole). It measures the wrench w_s exerted by the distal side on
the proximal side, in the sensor frame (rows [f; m]). The torque of every joint between
the base and a sensor is then given by the recursive Newton–Euler algorithm (Pinocchio
``rnea``) on the *proximal* model — bodies beyond the sensor removed, the carrying body
reduced to its proximal inertia I_k − ᵏX_s* I_distal — with w_s applied as an external
wrench at the sensor frame:

    τ = rnea_prox(q, q̇, q̈) − Σ_s J_sᵀ w_s .

The base motion comes from the IMU, and the base pose is never needed: the dynamics are
written in the base frame (base placement = identity), the base twist is [0, ω] (a uniform
translation velocity does not change internal forces), and gravity is replaced by the
specific force the accelerometer measures (equivalence principle):

    a_base = [f_O, ω̇],   f_O = R_bi f_imu − ω̇ × p_bi − ω × (ω × p_bi)   (model gravity = 0)

with (R_bi, p_bi) the IMU placement on the base, ω = R_bi ω_imu and ω̇ optional
(0 when not given). On a fixed-base model the base does not move: gravity is −f_O
(so an IMU on a tilted fixed base gives the right gravity direction) or the model's
gravity when there is no IMU.

Unknown wrench: one more wrench w_u at a chosen frame (e.g. a foot without sensor) is
solved by least squares from the rows that carry no actuator (the 6 base rows of a
floating base, plus unactuated joints): min ‖τ₀[U] − J_uᵀ[U] w_u‖, and reported. Joint
torques then subtract J_uᵀ w_u. Joints beyond a sensor get their torque from the full
model with no external wrench (they are not observed by the sensor).

Per sample: one Pinocchio ``rnea`` (plus one frame Jacobian with an unknown wrench).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..errors import NonFiniteError, RobotModelError, ShapeMismatchError
from ..parameters import pin_inertia
from ..robot import Robot

__all__ = ["FTSensor", "ImuSpec", "JointTorqueEstimate", "JointTorqueEstimator"]


@dataclass(frozen=True)
class FTSensor:
    """A 6-axis force/torque sensor at Pinocchio frame ``frame``.

    ``distal_inertia``: inertia of the part of the carrying body beyond the sensor (e.g.
    the foot sole plate), expressed in the sensor frame; None if that part is massless.
    Measurement convention: wrench [fx fy fz mx my mz] exerted by the distal side on the
    proximal side, in the sensor frame (a foot standing on the ground reads +fz up when
    the sensor z axis points up).
    """

    name: str
    frame: str
    distal_inertia: pin.Inertia | None = None


@dataclass(frozen=True)
class ImuSpec:
    """IMU rigidly attached to the base body at Pinocchio frame ``frame``.

    Gyro: angular velocity of the base [rad/s]; accelerometer: specific force
    a − g [m/s²] (reads +9.81 along the up axis at rest); both in the IMU frame.
    """

    frame: str


@dataclass
class JointTorqueEstimate:
    tau: np.ndarray  # (N, n_joints), columns = joint_names
    joint_names: tuple[str, ...]
    unknown_wrench: np.ndarray | None = None  # (N, 6) in the LOCAL frame of unknown_wrench_frame
    unknown_wrench_frame: str | None = None
    unactuated_residual: np.ndarray | None = None  # (N, |U|) rows that should be 0 after the fit
    settings: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        out = {"joints": list(self.joint_names), "settings": self.settings, "n_samples": int(self.tau.shape[0])}
        if self.unknown_wrench is not None:
            out["unknown_wrench_frame"] = self.unknown_wrench_frame
            out["unknown_wrench_mean"] = self.unknown_wrench.mean(axis=0).tolist()
        return out


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3-vector cross product (np.cross is slow on single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _rows(x, n: int, width: int, what: str) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[None, :]
    if x.ndim != 2 or x.shape[1] != width:
        raise ShapeMismatchError(f"{what} must have {width} columns, got shape {x.shape}")
    if x.shape[0] != n:
        raise ShapeMismatchError(f"{what} has {x.shape[0]} samples, joint positions have {n}")
    bad = ~np.isfinite(x)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise NonFiniteError(f"{what} has a non-finite value at sample {i}, column {j}")
    return x


class JointTorqueEstimator:
    """Joint torques from F/T sensors + IMU + encoders (see module docstring).

    ``include_armature``: add the rotor inertia (``model.armature``) reflected at each
    joint; False (default) estimates the link-side torque that a joint-torque sensor
    after the gearbox would read.
    """

    def __init__(
        self,
        robot: Robot,
        sensors: Sequence[FTSensor] = (),
        imu: ImuSpec | None = None,
        unknown_wrench_frame: str | None = None,
        include_armature: bool = False,
    ) -> None:
        self.robot = robot
        self.sensors = tuple(sensors)
        self.imu = imu
        self.include_armature = include_armature
        m = robot.model
        names = [s.name for s in self.sensors]
        if len(set(names)) != len(names):
            raise RobotModelError(f"duplicate F/T sensor names {names}")
        if robot.floating_base and imu is None:
            raise RobotModelError(
                f"{robot.name}: a floating-base model needs an IMU on the base (ImuSpec) to know the base motion"
            )
        self._full = m.copy()
        if not include_armature:
            self._full.armature[:] = 0.0
        self._prox = self._full.copy()
        if robot.floating_base:
            self._full.gravity = pin.Motion.Zero()
            self._prox.gravity = pin.Motion.Zero()
        self._model_gravity = m.gravity.linear.copy()

        # sensors: carrying joint, placement, proximal inertias, bodies beyond the sensor
        self._sensor_joint: list[int] = []
        self._sensor_placement: list[pin.SE3] = []
        beyond: set[int] = set()
        for s in self.sensors:
            fid = robot.frame_id(s.frame)
            k = int(m.frames[fid].parentJoint)
            if k == 0:
                raise RobotModelError(f"F/T sensor '{s.name}': frame '{s.frame}' is attached to the universe")
            X = m.frames[fid].placement
            desc = {int(i) for i in m.subtrees[k]} - {k}
            if k in beyond or k in self._sensor_joint or any(ko in desc for ko in self._sensor_joint):
                raise RobotModelError(f"F/T sensor '{s.name}' is nested with another sensor; nested sensors are not supported")
            beyond |= desc
            self._sensor_joint.append(k)
            self._sensor_placement.append(X)
            if s.distal_inertia is not None:
                pi = m.inertias[k].toDynamicParameters() - X.act(s.distal_inertia).toDynamicParameters()
                self._prox.inertias[k] = pin_inertia(pi)
        for j in beyond:
            self._prox.inertias[j] = pin.Inertia.Zero()
        self._beyond_v = sorted(int(m.joints[j].idx_v) for j in beyond)
        self._dp = self._prox.createData()
        self._df = self._full.createData() if beyond else None

        # IMU placement on the base
        if imu is not None:
            fid = robot.frame_id(imu.frame)
            root = 1 if robot.floating_base else 0
            if int(m.frames[fid].parentJoint) != root:
                raise RobotModelError(f"IMU frame '{imu.frame}' is not attached to the base body")
            pl = m.frames[fid].placement
            self._R_bi, self._p_bi = pl.rotation.copy(), pl.translation.copy()

        # unknown wrench
        self.unknown_wrench_frame = unknown_wrench_frame
        if unknown_wrench_frame is not None:
            fid = robot.frame_id(unknown_wrench_frame)
            if int(m.frames[fid].parentJoint) in beyond:
                raise RobotModelError(f"unknown-wrench frame '{unknown_wrench_frame}' lies beyond an F/T sensor")
            self._uw_fid = fid
            act = {int(i) for i in robot.actuated_v_indices}
            first = 6 if robot.floating_base else 0
            self._U = np.array(list(range(first)) + [i for i in range(first, m.nv) if i not in act], dtype=int)
            if self._U.size < 6:
                raise RobotModelError(
                    f"an unknown wrench needs ≥ 6 unactuated rows (a floating base, or passive joints); "
                    f"'{robot.name}' has {self._U.size}"
                )
        self._fext = pin.StdVec_Force()
        for _ in range(m.njoints):
            self._fext.append(pin.Force.Zero())
        self._jv = np.array([robot.v_index(n) for n in robot.joint_names], dtype=int)
        self._q = pin.neutral(m)
        self._v = np.zeros(m.nv)
        self._a = np.zeros(m.nv)

    # ---- one sample ----------------------------------------------------------------------
    def _base(self, gyro, acc, dgyro):
        if self.imu is None:
            return np.zeros(3), np.zeros(3), None
        w = self._R_bi @ gyro if gyro is not None else np.zeros(3)
        dw = self._R_bi @ dgyro if dgyro is not None else np.zeros(3)
        p = self._p_bi
        f_O = self._R_bi @ acc - _cross(dw, p) - _cross(w, _cross(w, p))
        return w, dw, f_O

    def step(self, q, dq, ddq, wrenches: Sequence[np.ndarray] = (), gyro=None, acc=None, dgyro=None):
        """Joint torques (n_joints,) of one sample; wrenches in ``sensors`` order.

        Returns ``(tau, unknown_wrench or None, residual or None)``. No input checking
        (use :meth:`estimate` for logs)."""
        robot, m = self.robot, self._prox
        fb = robot.floating_base
        w, dw, f_O = self._base(gyro, acc, dgyro)
        if fb:
            self._q[:7] = (0, 0, 0, 0, 0, 0, 1)
            self._q[7:] = 0.0
        q_full = self._q
        self._fill(q_full, self._v, self._a, q, dq, ddq)
        if fb:
            self._v[:6] = (0, 0, 0, *w)
            self._a[:6] = (*f_O, *dw)
        elif f_O is not None:
            m.gravity = pin.Motion(-f_O, np.zeros(3))
            if self._df is not None:
                self._full.gravity = m.gravity
        fext = self._fext
        for k in self._sensor_joint:
            fext[k] = pin.Force.Zero()
        for k, X, ws in zip(self._sensor_joint, self._sensor_placement, wrenches):
            fext[k] = fext[k] + X.act(pin.Force(np.asarray(ws, float)))
        tau_full = pin.rnea(m, self._dp, q_full, self._v, self._a, fext).copy()
        if self._df is not None:
            tf = pin.rnea(self._full, self._df, q_full, self._v, self._a)
            tau_full[self._beyond_v] = tf[self._beyond_v]
        wu = res = None
        if self.unknown_wrench_frame is not None:
            J = pin.computeFrameJacobian(m, self._dp, q_full, self._uw_fid, pin.LOCAL)
            A = J[:, self._U].T
            wu, *_ = np.linalg.lstsq(A, tau_full[self._U], rcond=None)
            tau_full = tau_full - J.T @ wu
            res = tau_full[self._U]
        return tau_full[self._jv], wu, res

    def _fill(self, q_full, v_full, a_full, q, dq, ddq) -> None:
        r = self.robot
        if not hasattr(self, "_qmap"):
            self._qmap = [(r.q_index(n), r.v_index(n), r.is_continuous(n)) for n in r.joint_names]
            self._simple = not any(c for _, _, c in self._qmap)
            self._iq = np.array([m[0] for m in self._qmap], dtype=int)
        if self._simple:
            q_full[self._iq] = q
            v_full[self._jv] = dq
            a_full[self._jv] = ddq
            return
        for i, (iq, iv, cont) in enumerate(self._qmap):
            if cont:
                q_full[iq], q_full[iq + 1] = np.cos(q[i]), np.sin(q[i])
            else:
                q_full[iq] = q[i]
            v_full[iv] = dq[i]
            a_full[iv] = ddq[i]

    # ---- logs ------------------------------------------------------------------------------
    def estimate(
        self,
        q: np.ndarray,
        dq: np.ndarray,
        ddq: np.ndarray,
        wrenches: Mapping[str, np.ndarray] | np.ndarray | None = None,
        gyro: np.ndarray | None = None,
        acc: np.ndarray | None = None,
        dgyro: np.ndarray | None = None,
    ) -> JointTorqueEstimate:
        """Joint torques of a log: q, dq, ddq (N, n_joints) in ``robot.joint_names`` order;
        ``wrenches`` {sensor name: (N, 6)} (or one (N, 6) array with a single sensor);
        gyro, acc, dgyro (N, 3) in the IMU frame."""
        n = len(self.robot.joint_names)
        q = np.atleast_2d(np.asarray(q, float))
        N = q.shape[0]
        q = _rows(q, N, n, "q")
        dq, ddq = _rows(dq, N, n, "dq"), _rows(ddq, N, n, "ddq")
        if wrenches is None:
            wrenches = {}
        if not isinstance(wrenches, Mapping):
            if len(self.sensors) != 1:
                raise ShapeMismatchError(f"pass wrenches as {{name: (N, 6)}} for the {len(self.sensors)} sensors")
            wrenches = {self.sensors[0].name: wrenches}
        missing = [s.name for s in self.sensors if s.name not in wrenches]
        unknown = [k for k in wrenches if k not in {s.name for s in self.sensors}]
        if missing or unknown:
            raise ShapeMismatchError(f"wrenches: missing sensor(s) {missing}, unknown sensor(s) {unknown}")
        W = [_rows(wrenches[s.name], N, 6, f"wrench '{s.name}'") for s in self.sensors]
        if self.imu is not None:
            if acc is None:
                raise ShapeMismatchError("the estimator has an IMU: pass acc (N, 3) (and gyro for a floating base)")
            acc = _rows(acc, N, 3, "acc")
            gyro = _rows(gyro, N, 3, "gyro") if gyro is not None else None
            dgyro = _rows(dgyro, N, 3, "dgyro") if dgyro is not None else None
            if self.robot.floating_base and gyro is None:
                raise ShapeMismatchError("a floating base needs gyro (N, 3)")
        tau = np.empty((N, n))
        has_u = self.unknown_wrench_frame is not None
        wu = np.empty((N, 6)) if has_u else None
        res = np.empty((N, self._U.size)) if has_u else None
        for i in range(N):
            t, w_, r_ = self.step(
                q[i], dq[i], ddq[i], [w[i] for w in W],
                None if gyro is None else gyro[i], None if acc is None else acc[i],
                None if dgyro is None else dgyro[i],
            )
            tau[i] = t
            if has_u:
                wu[i], res[i] = w_, r_
        settings = {
            "sensors": [{"name": s.name, "frame": s.frame, "distal_mass": 0.0 if s.distal_inertia is None else float(s.distal_inertia.mass)} for s in self.sensors],
            "imu_frame": None if self.imu is None else self.imu.frame,
            "include_armature": self.include_armature,
            "floating_base": self.robot.floating_base,
        }
        return JointTorqueEstimate(tau, tuple(self.robot.joint_names), wu, self.unknown_wrench_frame, res, settings)
