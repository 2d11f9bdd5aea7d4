"""Command: ``sensorless stream`` (the collision monitor one sample at a time, stdin/UDP/ROS 2; its benchmark,
``sensorless benchmark stream``, is in the studies package)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from ..errors import OptionError
from .applied_model import MODEL_HELP, robot_and_model
from .common import app, guarded, model_options, output_file, path_inputs, robot_source_options
from .frames import frame_options
from .options import ForceReference

__all__ = ["stream"]


@app.command()
@guarded
@robot_source_options
@frame_options
@model_options(MODEL_HELP, required=False)
def stream(
    robot: str,
    model: Optional[Path],
    thresholds: Path = typer.Option(..., help="monitor.json (or its folder) from `sensorless monitor` of this model on "
                                    "a contact-free log at the stream's sample rate: thresholds, observer gain and "
                                    "order, sample period, rest speeds"),
    input: str = typer.Option("stdin", "--input", help="where samples come from: stdin, udp://127.0.0.1:PORT (one "
                              "record per datagram, an empty datagram ends) or ros2:/joint_states (needs rclpy)"),
    output: str = typer.Option("stdout", help="where estimates go: stdout, udp://127.0.0.1:PORT, or ros2:PREFIX (with "
                               "a ros2 input; default /sensorless)"),
    format: str = typer.Option("csv", "--format", help="record encoding: csv or binary (little-endian float64; "
                               "docs/monitoring.md, 'Streaming')"),
    output_format: Optional[str] = typer.Option(None, help="encoding of the estimates (default: --format)"),
    frame: Optional[str] = typer.Option(None, help="frame at which to estimate the Cartesian force (fx, fy, fz)"),
    reference: ForceReference = typer.Option(ForceReference.local_world_aligned, help="frame of the force"),
    min_duration: Optional[float] = typer.Option(None, help="flag a contact once its crossing has lasted this long "
                                                 "[s] (default: the monitor's --min-duration)"),
    skip_bad: bool = typer.Option(False, "--skip-bad", help="count and skip bad records instead of stopping at the first"),
    allow_remote: bool = typer.Option(False, "--allow-remote", help="allow a UDP address that is not the loopback"),
    summary: Optional[Path] = typer.Option(None, help="also write the summary (counts, latency, settings) as JSON here "
                                           "(atomically; never inside the model or thresholds folder)"),
    force: bool = typer.Option(False, help="replace --summary if it exists"),
) -> None:
    """Monitor a live robot: read samples (seq, t, q, v, τ) from stdin, a UDP socket on the loopback or a
    ROS 2 topic; write per sample the external torque, the force at --frame and the contact flag.
    Memory stays bounded; end of input, SIGINT or SIGTERM stop it cleanly with a one-line summary on stderr
    (samples, drops from sequence gaps, latency p50/p99/max). docs/monitoring.md, 'Streaming'."""
    import dataclasses

    from ..estimation.momentum import MomentumDynamics
    from ..realtime import FORMATS, StreamMonitor, StreamThresholds, parse_endpoint, run_stream

    fmts = {"input": format, "output": output_format or format}
    for name, f in fmts.items():
        if f not in FORMATS:
            raise OptionError(f"--{'format' if name == 'input' else 'output-format'} {f}: choose csv or binary")
    src = parse_endpoint(input, "--input", allow_remote)
    dst = parse_endpoint(output, "--output", allow_remote)
    if dst.kind == "ros2" and src.kind != "ros2":
        raise OptionError(f"--output {output}: ROS 2 topics are published by a ros2: --input only")
    if src.kind == "ros2" and dst.kind == "udp":
        raise OptionError("--input ros2:… publishes on ROS 2 topics: leave --output out or give ros2:PREFIX")
    if summary is not None:  # refused before the first sample, not after the stream
        output_file(summary, path_inputs(robot, model, thresholds), force)
    th = StreamThresholds.read(thresholds)
    if min_duration is not None:
        if not min_duration >= 0:
            raise OptionError(f"--min-duration must be ≥ 0 seconds, got {min_duration}")
        th = dataclasses.replace(th, min_duration=float(min_duration))
    _, art = robot_and_model(robot, model)
    _same_model(th, art.path, thresholds)
    mon = StreamMonitor(MomentumDynamics(art.structure, art.parameters), th, frame, str(reference))
    mon.prime()
    if src.kind == "ros2":
        from ..realtime.ros2 import run_ros2

        stats = run_ros2(mon, src.topic, dst.topic if dst.kind == "ros2" else "/sensorless", skip_bad)
    else:
        stats = run_stream(mon, src, dst, fmts["input"], out_fmt=fmts["output"], skip_bad=skip_bad)
    sys.stderr.write(stats.line() + "\n")
    sys.stderr.flush()
    if summary is not None:
        from ..io import write_json_atomic

        doc = {**stats.to_dict(), "model": str(art.path), "model_label": art.label, "robot": robot,
               "input": str(src), "output": str(dst), "format": fmts, "frame": frame,
               "reference": str(reference) if frame else None, "records": mon.layout.describe(),
               "thresholds": th.settings(), "sample_bounds": mon.guard.settings(),
               "observer_step": "compiled" if mon.observer.compiled else f"python ({mon.observer.compiled_reason})"}
        write_json_atomic(doc, output_file(summary, path_inputs(robot, model, thresholds), force))


def _same_model(th, model_path, given) -> None:
    """OptionError when the thresholds were measured with another model file than the one applied."""
    if not th.model:
        return
    a, b = Path(th.model), Path(model_path)
    if a.exists() and b.exists() and not a.samefile(b):
        raise OptionError(f"--thresholds {given} were measured with the model {th.model}, not {model_path}: run "
                          "`sensorless monitor` with this --model")
