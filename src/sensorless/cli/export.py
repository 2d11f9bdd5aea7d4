"""`sensorless export`: an identified model in another format (MJCF, for MuJoCo)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .applied_model import passive_option, robot_and_model
from .common import app, floating_base_option, force_option, guarded, lock_option, output_file, path_inputs
from .console import console


@app.command()
@guarded
def export(
    model: Path = typer.Option(..., help="model folder (from `sensorless identify`)"),
    robot: str = typer.Option(..., help="the robot the model was identified on (URDF, MJCF or a registry name)"),
    mjcf: Path = typer.Option(..., help="MJCF file to write (MuJoCo: inertials, armature, damping, frictionloss)"),
    lock: Optional[List[str]] = lock_option("joints to lock (default: the model's, settings.robot)"),
    passive: Optional[List[str]] = passive_option(),
    floating_base: Optional[bool] = floating_base_option(),
    force: bool = force_option(),
) -> None:
    """Write the identified model as MJCF: each body's mass, CoM and inertia, each joint's armature
    (rotor inertia), damping (viscous friction) and frictionloss (Coulomb friction), each value's
    verdict (data / prior / undetermined) in a comment. A robot read from an MJCF file keeps that
    file's structure (geoms, sites, actuators, options); the header names the friction terms MuJoCo
    cannot express (offset, Stribeck, the Coulomb transition width, …) with their values."""
    from ..identification.artifact import export_mjcf

    output_file(mjcf, path_inputs(robot, model), force)
    r, art = robot_and_model(robot, model, lock=lock, passive=passive, floating=floating_base)
    path = export_mjcf(art, r, mjcf)
    console.print(f"model: {art.label}", highlight=False, soft_wrap=True)
    console.print(f"wrote {path}")
