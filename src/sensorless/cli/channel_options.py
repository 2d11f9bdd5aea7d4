"""Options for the floating-base channels of a log: the base twist from the logged pose
(:func:`sensorless.data.base_pose.base_motion_from_pose`) and wrenches logged in model frames
(:mod:`sensorless.data.wrench_frames`)."""

from __future__ import annotations

from typing import Optional

import typer

__all__ = ["base_velocity_option", "pose_max_gap_option", "wrench_frame_option"]


def base_velocity_option(default: Optional[str] = "auto"):
    return typer.Option(default, help="floating base: auto (the base twist and acceleration from the logged base pose "
                        "'base_q' when no 'base_v' is logged) | from-pose (always) | logged"
                        + ("" if default else "; default: the model's, else auto"))


def pose_max_gap_option():
    return typer.Option(None, help="--base-velocity from the pose: refuse a gap (repeated or missing pose samples) "
                                   "longer than this many median pose periods (default 10); repeats at the ends are "
                                   "clipped with a warning")


def wrench_frame_option():
    return typer.Option(None, help="wrench mode: model frame each measured wrench is logged in (sole, F/T sensor), one "
                                   "per --contact-frames entry in that order (comma-separated or repeated), 'contact' "
                                   "for each contact's own frame, 'world' for world axes at the contact (default); "
                                   "expressed in world axes at the contact frames with the logged kinematics")
