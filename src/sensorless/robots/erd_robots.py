"""The robots of example-robot-data (``panda``, ``ur5``, ``solo12``, ``talos``, ...): one registry entry
for its whole catalogue, loaded without meshes where it can be."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = ["ExampleRobotData", "erd_model"]


def _catalogue() -> dict:
    import example_robot_data as erd

    return erd.robots_loader.ROBOTS


@dataclass(frozen=True)
class ExampleRobotData:
    """Every name of example-robot-data's catalogue (``names``: computed on use)."""

    description = "an example-robot-data robot"
    in_code = False
    coupled = False

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(sorted(_catalogue()))

    def matches(self, name: str) -> bool:
        return name in _catalogue()

    def load(self, name: str, floating_base: "bool | None" = None):
        """(model, name, source, URDF path); ``floating_base=False`` removes a catalogue free-flyer."""
        import numpy as np
        import pinocchio as pin

        model, urdf = erd_model(name)
        if floating_base is False and model.joints[1].shortname() == "JointModelFreeFlyer":
            model.lowerVelocityLimit = -np.abs(model.upperVelocityLimit)
            model = pin.buildReducedModel(model, [1], pin.neutral(model))
        return model, name, f"example-robot-data:{name}", urdf


def erd_model(name: str) -> "tuple[pin.Model, str | None]":
    """The kinematic/inertial model of an example-robot-data robot and its URDF path, loaded once.

    ``erd.load`` builds the visual and collision geometry too (meshes: most of its time). For the
    loaders that only run ``RobotLoader.__init__`` the same model is built here from the URDF path
    without geometry, with the same SRDF step (rotor parameters → armature, reference postures) and
    free-flyer limits; loaders with their own ``__init__`` (e.g. ``talos_legs``) go through ``erd.load``.
    """
    import pinocchio as pin
    from example_robot_data.utils import RobotLoader, getModelPath, readParamsFromSrdf

    loader = _catalogue()[name]
    if loader.__init__ is not RobotLoader.__init__ or not loader.urdf_filename or loader.sdf_filename:
        wrapper = loader()
        return wrapper.robot.model, str(getattr(wrapper, "df_path", None) or "") or None
    rel = os.path.join(loader.path, loader.urdf_subpath, loader.urdf_filename)
    root = loader.model_path or getModelPath(rel)
    urdf = os.path.join(root, rel)
    model = pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer()) if loader.free_flyer else pin.buildModelFromUrdf(urdf)
    if loader.srdf_filename:
        srdf = os.path.join(root, loader.path, loader.srdf_subpath, loader.srdf_filename)
        readParamsFromSrdf(model, srdf, False, loader.has_rotor_parameters, loader.ref_posture)
    if loader.free_flyer:  # RobotLoader.addFreeFlyerJointLimits
        ub, lb = model.upperPositionLimit, model.lowerPositionLimit
        ub[:7], lb[:7] = 1, -1
        model.upperPositionLimit, model.lowerPositionLimit = ub, lb
    return model, urdf
