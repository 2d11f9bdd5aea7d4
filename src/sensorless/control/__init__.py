"""Torque control of position-controlled robots: gains, inverse dynamics, torque feedback, the loop."""

from .gains import (
    DeltaQGains,
    TorqueGains,
    damped_gains,
    from_delta_q_gains,
    to_delta_q_gains,
)
from .inverse_dynamics import InverseDynamics, contact_wrench_from_ft
from .loop import ContactSpec, Reference, StreamingSavgol, TorqueControlLoop
from .torque_controller import JointTorqueController

__all__ = [
    "ContactSpec",
    "DeltaQGains",
    "InverseDynamics",
    "JointTorqueController",
    "Reference",
    "StreamingSavgol",
    "TorqueControlLoop",
    "TorqueGains",
    "contact_wrench_from_ft",
    "damped_gains",
    "from_delta_q_gains",
    "to_delta_q_gains",
]
