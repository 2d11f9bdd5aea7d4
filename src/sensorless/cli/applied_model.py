"""The robot and the model a command applies (predict, estimate-force, monitor, payload).

One function, :func:`robot_and_model`. With an identified model the robot description is loaded
as it was for the fit (``settings.robot`` of the model: floating base, locked and passive joints,
frames added with ``--add-frame``; :mod:`sensorless.identification.artifact`), so nothing is
repeated on the command line: ``--lock``/``--passive``/``--floating-base`` may be left out, and
when given they must agree with the model. Without ``--model``, or with a robot description file
as ``--model`` (``robot.urdf``), the description itself is the model: its inertial parameters and
armature, no friction, labelled as the prior in every output (``ModelArtifact.origin``).
"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..errors import OptionError, SensorlessError
from .common import (load_robot_arg, log_reading_options, model_options, model_preprocessing_options,
                     robot_source_options)
from .frames import frame_options

__all__ = ["MODEL_HELP", "applied_model_options", "passive_option", "robot_and_model"]

MODEL_HELP = ("identified model: result.json (or its directory) from `sensorless identify`; or a robot description "
              "(.urdf/.xml) whose own inertial parameters are the model (the prior, no friction); default: --robot's own")


def applied_model_options(model_help: str = MODEL_HELP, *, robot_required: bool = True, frames: bool = False):
    """Decorator: the options of a command that applies a model to a log, in this order: the robot
    source, ``--add-frame`` (with ``frames``), the model's preprocessing (``prep``), ``--robot`` and an
    optional ``--model`` (help ``model_help``; ``--robot`` optional unless ``robot_required``) and the
    log-reading options. One definition for predict, monitor and estimate-force."""

    def deco(fn):
        fn = model_options(model_help, required=False, robot_required=robot_required)(log_reading_options()(fn))
        fn = model_preprocessing_options()(fn)
        return robot_source_options(frame_options(fn) if frames else fn)

    return deco


def passive_option():
    return typer.Option(None, help="joint without an actuator (repeatable): no torque is logged for it, its generalized "
                                   "force is 0 apart from its own friction (a rail, a free pivot)")


def robot_and_model(robot: str, model: Optional[Path], *, lock: Optional[List[str]] = None,
                    passive: Optional[List[str]] = None, floating: Optional[bool] = None):
    """(Robot, :class:`~sensorless.identification.artifact.ModelArtifact`) of a command (module docstring)."""
    from ..identification.artifact import is_robot_description, load_model_folder, prior_model, read_robot_settings

    if model is None or is_robot_description(model):
        r = load_robot_arg(robot, lock, floating, passive)
        desc = None if model is None else load_robot_arg(str(model), lock, getattr(r, "floating_base", None), passive)
        return r, prior_model(r, desc, source=model if model is not None else robot)
    try:
        stored = read_robot_settings(model)
    except SensorlessError:
        load_robot_arg(robot, lock, floating, passive)  # a robot that cannot load (an untrusted xacro) is said first
        raise
    lock = _agree("--lock", lock, stored.get("lock"), model)
    passive = _agree("--passive", passive, stored.get("passive"), model)
    if floating is not None and "floating_base" in stored and floating != stored["floating_base"]:
        flag = "--floating-base" if stored["floating_base"] else "--fixed-base"
        raise OptionError(f"{'--floating-base' if floating else '--fixed-base'}: the model {model} was identified with "
                          f"{flag} (settings.robot); the robot is loaded as for the fit: leave the option out")
    r = load_robot_arg(robot, lock, stored.get("floating_base", floating), passive)
    from ..robot import add_frame

    tree = getattr(r, "tree", r)
    for name, parent, xyz, rpy in stored.get("frames", ()):
        if not tree.model.existFrame(name):  # the same --add-frame given again is no conflict
            add_frame(r, name, parent, xyz, rpy)
    return r, load_model_folder(model, r)


def _agree(flag: str, given: Optional[List[str]], stored: Optional[List[str]], model) -> Optional[List[str]]:
    """The stored joints (a model written before settings.robot: the given ones); a different set given is an error."""
    if stored is None:
        return given
    if given and sorted(given) != sorted(stored):
        was = " ".join(f"{flag} {j}" for j in stored) or f"no {flag}"
        raise OptionError(f"{flag} {' '.join(given)}: the model {model} was identified with {was} (settings.robot); "
                          f"the robot is loaded as for the fit: leave {flag} out")
    return list(stored)
