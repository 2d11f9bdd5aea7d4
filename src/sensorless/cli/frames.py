"""`sensorless frames`: every frame of a robot model; ``--add-frame`` for the commands that
take a frame (payload, estimate-force, monitor, identify)."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import List, Optional

import typer

from .common import ADDED_FRAMES, add_options, app, guarded, load_robot_arg, lock_option, robot_option
from .console import console
from .common import floating_base_option, output_file, path_inputs, robot_source_options

__all__ = ["ADD_FRAME_OPTION", "frame_options", "frames"]

ADD_FRAME_HELP = ("add a frame at a known location: NAME:PARENT:x,y,z[:roll,pitch,yaw] [m, rad] in the axes of "
                  "frame PARENT (repeatable; `sensorless frames` lists the model's frames)")


ADD_FRAME_OPTION = {"add_frame": (Optional[List[str]], lambda: typer.Option(None, help=ADD_FRAME_HELP))}


def frame_options(fn):
    """Decorator: ``--add-frame`` (repeatable); :func:`~.common.load_robot_arg` adds the frames
    to the robot it loads while the command runs."""

    @functools.wraps(fn)
    def run(*args, add_frame: Optional[List[str]] = None, **kwargs):
        from ..run.model import parse_add_frame

        token = ADDED_FRAMES.set(tuple(parse_add_frame(s) for s in add_frame or ()))
        try:
            return fn(*args, **kwargs)
        finally:
            ADDED_FRAMES.reset(token)

    return add_options(ADD_FRAME_OPTION)(run)


@app.command()
@guarded
@robot_source_options
@frame_options
def frames(
    robot: str = robot_option(),
    out: Optional[Path] = typer.Option(None, help="also write the table as JSON"),
    lock: Optional[List[str]] = lock_option(),
    floating_base: Optional[bool] = floating_base_option(),
) -> None:
    """List every frame of ROBOT: its type, parent joint and frame, origin and rotation in the
    parent joint's axes, and world origin and axes at zero joint values."""
    from ..io import write_json_atomic
    from ..robot import frame_table

    if out is not None:
        output_file(out, path_inputs(robot))
    rows = frame_table(load_robot_arg(robot, lock, floating_base))
    console.print(f"{len(rows)} frames of {robot}: parent joint / parent frame, origin and rpy in the parent "
                  "joint's axes, world origin and axes x | y | z at zero joint values", highlight=False)

    def v(x):
        return "(" + ", ".join(f"{round(a, 4) + 0.0:g}" for a in x) + ")"

    for r in rows:
        console.print(f"{r['name']} [{r['type']}]  parent {r['parent_joint']} / {r['parent_frame'] or '-'}  "
                      f"xyz {v(r['xyz'])} rpy {v(r['rpy'])}  world {v(r['world_origin'])} axes "
                      + " | ".join(v(a) for a in r["world_axes"]), highlight=False, markup=False, soft_wrap=True)
    if out is not None:
        write_json_atomic({"robot": str(robot), "frames": rows}, out)
        console.print(f"wrote {out}")
