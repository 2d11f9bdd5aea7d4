"""What ``sensorless monitor`` reports from a momentum observer's output r (:mod:`.momentum`).

r ≈ L(s)[τ_ext] is the external generalized force acting on the robot, on every coordinate.
The reported external torque follows estimate-force's sign, τ_ext = −r (what the robot exerts on
its environment), on the rows where the generalized force is known:

* a per-joint model: the actuated joints (τ measured) and the passive joints (generalized force 0:
  a force pushing a leg along its rail shows on the rail's row); a transmission: its coordinates;
* a model identified with contacts (:class:`~sensorless.regressor.contact.ContactStructure`): in
  stance r holds the expected contact forces, Σ Jcᵀ f. What the contacts cannot explain is the
  projected residual P(q) r, P = I − Jc⁺Jc of the contacts active at that sample (the projector of
  the identification, flags from the log or detected), reported on every row (a floating base's 6,
  then every joint). In flight P = I.

A force at a frame is then F = argmin ‖P Jᵀ F − P τ_ext‖ (damped least squares of :mod:`.force`;
P = I without contacts): with contacts only the part of the frame's force that the feet cannot
take is seen.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.trajectory import Trajectory

__all__ = ["MonitoredTorque", "cartesian_force", "monitored_rows", "monitored_torque"]


@dataclass
class MonitoredTorque:
    """τ_ext (N, n) on the rows ``names`` (velocity indices ``rows``); ``projector`` (N, nv, nv) or None."""

    tau_ext: np.ndarray
    names: list[str]
    rows: np.ndarray
    projector: np.ndarray | None = None


def monitored_rows(dyn) -> tuple[list[str], np.ndarray, bool]:
    """(names, velocity indices, projected) of the rows :func:`monitored_torque` reports for ``dyn``
    (module docstring); a friction-only model (no ``structure``): its joints."""
    s = getattr(dyn, "structure", None)
    if s is None or dyn.transmission:
        rows = np.asarray(dyn.actuated_rows, dtype=int)
        return [dyn.names[i] for i in rows], rows, False
    robot = s.robot
    if getattr(s.row_map, "per_sample", False) and hasattr(s, "projector"):
        return list(dyn.names), np.arange(robot.nv), True
    rows = np.asarray(robot.term_v_indices, dtype=int)
    return [dyn.names[i] for i in rows], rows, False


def monitored_torque(dyn, r: np.ndarray, traj: Trajectory) -> MonitoredTorque:
    """The reported external torque from the observer output ``r`` (N, n) of ``dyn`` (module docstring)."""
    names, rows, projected = monitored_rows(dyn)
    if projected:
        s = dyn.structure
        P = s.projector(dyn.arrays(traj)[0], s.contacts(traj))
        return MonitoredTorque(-np.einsum("nij,nj->ni", P, r), names, rows, P)
    return MonitoredTorque(-r[:, rows], names, rows)


def cartesian_force(dyn, traj: Trajectory, mon: MonitoredTorque, frame: str, reference: str):
    """F at ``frame`` from the monitored torque (module docstring): a
    :class:`~.force.ForceEstimate`, NaN where a component is unobservable."""
    from .force import ForceEstimate, damped_least_squares, frame_jacobians

    Q = dyn.arrays(traj)[0]
    if dyn.transmission:  # τ_θ = Gᵀ Jᵀ F: the Jacobian in coordinates is J G
        st = dyn.structure
        Qt = st.tree.full_configuration(st.joint_values(Q))
        J = frame_jacobians(st.tree, Qt, frame, reference)[:, :3] @ st.G
    else:
        J = frame_jacobians(dyn.structure.robot, Q, frame, reference)[:, :3]
        if mon.projector is not None:  # P Jᵀ: the part of the frame's force the contacts cannot take
            J = np.einsum("nij,nkj->nki", mon.projector, J)
        J = J[:, :, mon.rows]
    sol = damped_least_squares(J, mon.tau_ext)  # the solver and NaN rule of estimate-force
    return ForceEstimate(traj.t, sol.F, ["fx", "fy", "fz"], frame, reference, mon.tau_ext, sol.sigma_min, sol.damping,
                         settings={"projected": mon.projector is not None}, unobservable=sol.unobservable)
