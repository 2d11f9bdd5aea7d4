"""A PSM-like remote-centre-of-motion (RCM) arm, built directly in Pinocchio.

Serial stand-in for a dVRK PSM (the parallelogram is replaced by two revolute joints
whose axes meet at the RCM; kinematically the same around the port):

====================  ==========  ==============================================
joint                 type        axis / meaning
====================  ==========  ==============================================
``outer_yaw``         revolute    world x through the RCM (world origin)
``outer_pitch``       revolute    y of the yaw frame, through the RCM
``insertion``         prismatic   along the shaft, positive = deeper (world −z at 0)
``roll``              revolute    about the shaft
``wrist_pitch``       revolute    x at the shaft tip
``wrist_yaw``         revolute    y, 9.1 mm further
====================  ==========  ==============================================

At q = 0 the instrument points straight down (−z); the shaft tip (``shaft_tip``
frame, origin of the insertion joint) sits ``q_insertion`` metres below the RCM and
the jaw tip (``tool_tip``) 10.2 mm past the wrist-yaw axis. Gravity is −z.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from sensorless.robot import Robot

__all__ = [
    "JAW_LENGTH",
    "JOINTS",
    "SHAFT_FRAME",
    "TIP_FRAME",
    "WRIST_LENGTH",
    "build_surgical_arm",
    "direction_to_angles",
]

JOINTS = ("outer_yaw", "outer_pitch", "insertion", "roll", "wrist_pitch", "wrist_yaw")
TIP_FRAME = "tool_tip"
SHAFT_FRAME = "shaft_tip"
WRIST_LENGTH = 0.0091  # wrist pitch → wrist yaw axis [m]
JAW_LENGTH = 0.0102  # wrist yaw axis → jaw tip [m]

# (mass [kg], CoM in the joint frame [m], principal inertia about the CoM [kg m²])
_BODIES = {
    "outer_yaw": (1.2, (0.0, 0.02, 0.10), (0.010, 0.008, 0.004)),
    "outer_pitch": (0.8, (0.01, 0.0, 0.18), (0.006, 0.006, 0.001)),
    "insertion": (0.5, (0.0, 0.0, -0.25), (0.004, 0.004, 2e-4)),
    "roll": (0.1, (0.0, 0.0, -0.20), (1.5e-3, 1.5e-3, 1e-5)),
    "wrist_pitch": (0.005, (0.0, 0.0, 0.004), (1e-7, 1e-7, 5e-8)),
    "wrist_yaw": (0.005, (0.0, 0.0, 0.005), (1e-7, 1e-7, 5e-8)),
}
_LIMITS = {  # lower, upper, velocity, effort
    "outer_yaw": (-1.0, 1.0, 2.0, 10.0),
    "outer_pitch": (-0.8, 0.8, 2.0, 10.0),
    "insertion": (0.0, 0.24, 0.4, 50.0),
    "roll": (-2.5, 2.5, 4.0, 1.0),
    "wrist_pitch": (-1.4, 1.4, 4.0, 1.0),
    "wrist_yaw": (-1.4, 1.4, 4.0, 1.0),
}
_ARMATURE = {"outer_yaw": 0.01, "outer_pitch": 0.01, "insertion": 0.3, "roll": 2e-4, "wrist_pitch": 1e-4, "wrist_yaw": 1e-4}


def build_surgical_arm(armature: bool = True) -> Robot:
    """The nominal (CAD) PSM-like arm as a :class:`~sensorless.robot.Robot` (6 actuated joints)."""
    model = pin.Model()
    model.name = "psm_like"
    down = pin.SE3(pin.utils.rotate("x", np.pi), np.zeros(3))  # local z = world −z at q = 0
    specs = [
        ("outer_yaw", pin.JointModelRX(), pin.SE3.Identity()),
        ("outer_pitch", pin.JointModelRY(), pin.SE3.Identity()),
        ("insertion", pin.JointModelPZ(), down),
        ("roll", pin.JointModelRZ(), pin.SE3.Identity()),
        ("wrist_pitch", pin.JointModelRX(), pin.SE3.Identity()),
        ("wrist_yaw", pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0.0, 0.0, WRIST_LENGTH]))),
    ]
    parent, parent_frame = 0, 0
    for name, joint, placement in specs:
        lo, hi, vmax, emax = _LIMITS[name]
        jid = model.addJoint(
            parent, joint, placement, name,
            np.array([emax]), np.array([vmax]), np.array([lo]), np.array([hi]),
        )
        m, c, I = _BODIES[name]
        model.appendBodyToJoint(jid, pin.Inertia(m, np.array(c), np.diag(I)), pin.SE3.Identity())
        jf = model.addJointFrame(jid, parent_frame)
        parent_frame = model.addBodyFrame(name + "_link", jid, pin.SE3.Identity(), jf)
        if armature:
            model.armature[model.joints[jid].idx_v] = _ARMATURE[name]
        parent = jid
    ins = model.getJointId("insertion")
    model.addFrame(pin.Frame(SHAFT_FRAME, ins, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    wy = model.getJointId("wrist_yaw")
    tip = pin.SE3(np.eye(3), np.array([0.0, 0.0, JAW_LENGTH]))
    model.addFrame(pin.Frame(TIP_FRAME, wy, 0, tip, pin.FrameType.OP_FRAME))
    return Robot(model, name="psm_like", source="sensorless_studies.simulation.surgical_arm")


def direction_to_angles(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(outer_yaw, outer_pitch) pointing the shaft (RCM → tip) along unit vector(s) ``u``.

    The shaft direction is Rx(yaw) Ry(pitch) (0, 0, −1) = (−sin p, cos p sin y, −cos p cos y).
    """
    u = np.asarray(u, dtype=float)
    pitch = -np.arcsin(np.clip(u[..., 0], -1.0, 1.0))
    yaw = np.arctan2(u[..., 1], -u[..., 2])
    return yaw, pitch
