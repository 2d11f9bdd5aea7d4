"""The TALOS right leg (example-robot-data ``talos_legs``) with an ankle F/T sensor and a base IMU.

Two views of the same leg, built from the same URDF so that their dynamics agree to
machine precision:

* :func:`talos_right_leg` — the Pinocchio :class:`~sensorless.robot.Robot` (fixed base:
  the free-flyer and the left leg are locked at neutral), with a sole plate below the F/T
  sensor appended to the ankle-roll body and the frames ``right_ankle_ft`` (sensor),
  ``right_foot_sole`` (sole centre, contact point) and ``base_imu``.
* :func:`right_leg_mjspec` — the MuJoCo scene (``mujoco.MjSpec``) from the URDF with
  meshes dropped, the same sole plate as a separate welded body (so that MuJoCo's
  force/torque sensor at its site measures the ankle–foot interaction), gyro and
  accelerometer on the base, rotor inertias as joint armature, and optionally a stiff
  floor under the foot.

Rotor inertia is *not* in the Pinocchio model (``armature`` = 0): estimator and controller
work with link-side torques; the rotor belongs to the actuator (simulated in MuJoCo).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from functools import lru_cache

import numpy as np
import pinocchio as pin

from sensorless.errors import RobotModelError
from sensorless.robot import Robot

__all__ = [
    "FT_FRAME",
    "FT_PLACEMENT",
    "IMU_FRAME",
    "IMU_PLACEMENT",
    "JOINTS",
    "PLATE_CENTRE",
    "PLATE_HALF_SIZE",
    "PLATE_MASS",
    "SOLE_FRAME",
    "plate_inertia",
    "right_leg_mjspec",
    "right_leg_urdf",
    "talos_right_leg",
]

JOINTS = tuple(f"leg_right_{i}_joint" for i in range(1, 7))
FT_FRAME = "right_ankle_ft"
SOLE_FRAME = "right_foot_sole"
IMU_FRAME = "base_imu"
# F/T sensor 8.7 cm below the ankle-roll axis, axes parallel to the ankle-roll joint frame
FT_PLACEMENT = pin.SE3(np.eye(3), np.array([0.0, 0.0, -0.087]))
IMU_PLACEMENT = pin.SE3(np.eye(3), np.array([-0.05, 0.0, 0.05]))  # on the pelvis (base_link)
PLATE_MASS = 0.6  # sole plate below the sensor [kg]
PLATE_HALF_SIZE = np.array([0.105, 0.065, 0.01])  # [m]
PLATE_CENTRE = np.array([0.01, 0.0, -0.01])  # in the sensor frame [m]
SOLE_IN_SENSOR = np.array([0.01, 0.0, -0.02])  # sole centre (bottom of the plate), sensor frame


def plate_inertia() -> pin.Inertia:
    """Inertia of the sole plate (solid box) in the sensor frame."""
    a, b, c = PLATE_HALF_SIZE
    m = PLATE_MASS
    I = np.diag([m / 3 * (b * b + c * c), m / 3 * (a * a + c * c), m / 3 * (a * a + b * b)])
    return pin.Inertia(m, PLATE_CENTRE, I)


def _erd_model() -> tuple[pin.Model, str]:
    import example_robot_data as erd

    loader = erd.robots_loader.ROBOTS["talos_legs"]()
    model = erd.load("talos_legs").model.copy()
    # example-robot-data leaves lowerVelocityLimit at +max, which buildReducedModel (Pinocchio 4) rejects
    model.lowerVelocityLimit = -np.abs(model.upperVelocityLimit)
    return model, str(loader.df_path)


def talos_right_leg(foot_plate: bool = True) -> Robot:
    """Fixed-base Pinocchio model of the TALOS right leg (6 joints) with sensor frames."""
    model, urdf = _erd_model()
    lock = [1] + [model.getJointId(f"leg_left_{i}_joint") for i in range(1, 7)]
    if model.joints[1].shortname() != "JointModelFreeFlyer":
        raise RobotModelError("example-robot-data talos_legs: expected a free-flyer root")
    red = pin.buildReducedModel(model, lock, pin.neutral(model))
    j6 = red.getJointId("leg_right_6_joint")
    if foot_plate:
        red.appendBodyToJoint(j6, FT_PLACEMENT.act(plate_inertia()), pin.SE3.Identity())
    red.addFrame(pin.Frame(FT_FRAME, j6, 0, FT_PLACEMENT, pin.FrameType.OP_FRAME))
    sole = pin.SE3(np.eye(3), FT_PLACEMENT.act(SOLE_IN_SENSOR))
    red.addFrame(pin.Frame(SOLE_FRAME, j6, 0, sole, pin.FrameType.OP_FRAME))
    red.addFrame(pin.Frame(IMU_FRAME, 0, 0, IMU_PLACEMENT, pin.FrameType.OP_FRAME))
    red.armature[:] = 0.0
    robot = Robot(red, name="talos_right_leg", source=f"example-robot-data:talos_legs ({urdf}), right leg, fixed base")
    robot.urdf_path = urdf
    return robot


@lru_cache(maxsize=1)
def right_leg_urdf() -> str:
    """URDF text of base_link + the right leg (no visual/collision meshes, fixed links kept)."""
    _, urdf = _erd_model()
    root = ET.parse(urdf).getroot()
    keep = {"base_link", "right_sole_link"} | {f"leg_right_{i}_link" for i in range(1, 7)}
    for el in list(root):
        if el.tag == "link" and el.get("name") not in keep or el.tag == "joint" and el.find("child").get("link") not in keep or el.tag not in ("link", "joint"):
            root.remove(el)
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for e in link.findall(tag):
                link.remove(e)
    mj = ET.SubElement(root, "mujoco")
    ET.SubElement(mj, "compiler", fusestatic="false", discardvisual="true")
    return ET.tostring(root, encoding="unicode")


def right_leg_mjspec(
    rotor_inertia: np.ndarray,
    floor_height: float | None = None,
    timestep: float = 5e-4,
    contact_timeconst: float = 0.004,
    friction_solimp: float = 0.9999,
):
    """MuJoCo scene of the leg (fixed base). ``floor_height``: z of a rigid-ish floor plane
    (None: hanging in the air). Joint friction (``frictionloss``) is set per step by the
    actuator model; its constraint is made stiff (``friction_solimp``) so that stiction holds."""
    import mujoco

    spec = mujoco.MjSpec.from_string(right_leg_urdf())
    spec.modelname = "talos_right_leg"
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    spec.option.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    for j, ia in zip(JOINTS, np.broadcast_to(rotor_inertia, (6,))):
        spec.joint(j).armature = float(ia)
        spec.joint(j).damping = [0.0, 0.0, 0.0]
        spec.joint(j).solimp_friction = [friction_solimp, friction_solimp, 0.001, 0.5, 2.0]
        spec.joint(j).solref_friction = [2 * timestep, 1.0]
    ankle = spec.body("leg_right_6_link")
    plate = ankle.add_body(name="right_foot_plate", pos=FT_PLACEMENT.translation.tolist())
    plate.add_geom(
        name="right_sole", type=mujoco.mjtGeom.mjGEOM_BOX, size=PLATE_HALF_SIZE.tolist(), pos=PLATE_CENTRE.tolist(),
        mass=PLATE_MASS, friction=[1.0, 0.02, 0.001], solref=[contact_timeconst, 1.0], condim=3,
    )
    plate.add_site(name="ft", pos=[0.0, 0.0, 0.0])
    plate.add_site(name="sole", pos=SOLE_IN_SENSOR.tolist())
    spec.body("base_link").add_site(name="imu", pos=IMU_PLACEMENT.translation.tolist())
    S, O = mujoco.mjtSensor, mujoco.mjtObj.mjOBJ_SITE
    spec.add_sensor(name="ft_force", type=S.mjSENS_FORCE, objtype=O, objname="ft")
    spec.add_sensor(name="ft_torque", type=S.mjSENS_TORQUE, objtype=O, objname="ft")
    spec.add_sensor(name="gyro", type=S.mjSENS_GYRO, objtype=O, objname="imu")
    spec.add_sensor(name="acc", type=S.mjSENS_ACCELEROMETER, objtype=O, objname="imu")
    if floor_height is not None:
        spec.worldbody.add_geom(
            name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2.0, 2.0, 0.1], pos=[0.0, 0.0, float(floor_height)],
            friction=[1.0, 0.02, 0.001], solref=[contact_timeconst, 1.0],
        )
    return spec
