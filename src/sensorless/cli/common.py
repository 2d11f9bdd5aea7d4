"""Shared CLI pieces: the typer apps, error guard, atomic output directories (progress bars: :mod:`.progress`)."""

from __future__ import annotations

import contextlib
import contextvars
import functools
import os
import warnings
from pathlib import Path
from typing import Iterable, Iterator, List, Optional

import typer
from typer.core import TyperCommand
from rich.text import Text

from .console import err_console, strip_control

from ..errors import SensorlessError
from .channel_options import base_velocity_option, pose_max_gap_option
from .blas import blas_threads_for_command
from .startup import before_scipy
from .flags import cli_words
from .logs import log_trims, trim_option
from .options import RATE_HELP, TIME_UNIT_HELP, AngleUnit, BaseVelocity, JointOrder, TimeFrom, TimeUnit, config_error, current_context
from ..run.logs import load_logs
from .plugins import PluginGroup

#: the root command; other packages add theirs through entry points (:mod:`.plugins`: the studies)
app = typer.Typer(cls=PluginGroup, add_completion=False, no_args_is_help=True,
                  help="Dynamic models for robots without torque or force sensors.")


#: placeholder in an option's help for the list of log formats (:func:`sensorless.data.formats.formats_help`),
#: filled when the help is shown (:class:`MultiValueCommand`): the CLI starts without loading the readers
LOG_FORMATS = "<log formats>"


class MultiValueCommand(TyperCommand):
    """A command whose repeatable options (``List[...]``) also take several values after one
    flag: ``--data a.csv b.csv c.csv`` is ``--data a.csv --data b.csv --data c.csv`` (a shell
    glob expands to exactly that). Values run until the next token starting with ``-``.
    Only for commands without positional arguments (nothing else could own a bare token).
    Usage errors (a value not among an option's choices, a missing option) are one red line too."""

    def format_help(self, ctx, formatter):
        """The help, with :data:`LOG_FORMATS` in an option's help replaced by the registered log formats."""
        if any(LOG_FORMATS in (getattr(p, "help", None) or "") for p in self.params):
            from ..data.formats import formats_help  # the registry (sensorless.data: loaded for the help only)

            for p in self.params:
                if LOG_FORMATS in (getattr(p, "help", None) or ""):
                    p.help = p.help.replace(LOG_FORMATS, formats_help())
        return super().format_help(ctx, formatter)

    def parse_args(self, ctx, args):
        if not any(p.param_type_name == "argument" for p in self.params):  # (typer may vendor its own click)
            args = expand_multi_values(args, {o for p in self.params if p.param_type_name == "option"
                                              and getattr(p, "multiple", False) for o in p.opts})
        try:
            return super().parse_args(ctx, args)
        except Exception as exc:
            if type(exc).__name__ not in ("BadParameter", "MissingParameter", "NoSuchOption", "BadOptionUsage",
                                          "UsageError") or not hasattr(exc, "format_message"):
                raise
            cause = config_error(ctx)  # a broken --config explains the missing option: name the cause
            _print_line("error:", "bold red", one_line(cli_words(cause)) if cause else
                        one_line(exc.format_message()).replace("Value error, ", ""))
            raise typer.Exit(2) from None


def expand_multi_values(args: list[str], multi: set[str]) -> list[str]:
    """``[--data, a, b, --x, 1]`` -> ``[--data, a, --data, b, --x, 1]`` for the flags in ``multi``."""
    out: list[str] = []
    cur, need_value = None, False
    for a in args:
        if need_value:  # the flag's own first value, whatever it looks like
            out.append(a)
            need_value = False
        elif a == "--":
            cur = None
            out.append(a)
        elif a.startswith("-") and len(a) > 1:
            name = a.split("=", 1)[0]
            cur = name if name in multi else None
            need_value = cur is not None and "=" not in a
            out.append(a)
        elif cur is not None:
            out += [cur, a]
        else:
            out.append(a)
    return out


def one_line(text: object, limit: int = 2000) -> str:
    """``text`` with every run of whitespace (newlines included) collapsed to one space."""
    flat = " ".join(str(text).split())
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def _print_line(label: str, style: str, message: str) -> None:
    # Text, not markup: messages may hold "[...]" (C++ diagnostics, lists) that rich would eat
    err_console.print(Text.assemble((label, style), " ", strip_control(message)), highlight=False, soft_wrap=True)


#: the warning lines the running command printed (each once), for the reports it writes
_PRINTED: list[str] = []


def printed_warnings() -> list[str]:
    """Every warning line the running command has printed so far, in order (its reports show them)."""
    return list(_PRINTED)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    name = getattr(category, "__name__", "Warning")
    prefix = "" if name in ("UserWarning", "IdentifiabilityWarning", "DataWarning") else f"{name}: "
    text = prefix + one_line(cli_words(message))
    if text in _PRINTED:  # one line per cause: the same warning again (another fold, another log part) adds nothing
        return
    _PRINTED.append(text)
    _print_line("warning:", "yellow", text)


def config_named_files() -> list[tuple[str, str]]:
    """(option, path) of the existing files the running command was given by ``--config`` only (a value
    from the file's table, not typed on the command line)."""
    ctx = current_context()
    if ctx is None or not hasattr(ctx, "get_parameter_source"):
        return []
    typed = set()
    out = []
    for name, value in ctx.params.items():
        src = getattr(ctx.get_parameter_source(name), "name", "")
        for v in (value if isinstance(value, (list, tuple)) else [value]):
            if not isinstance(v, (str, Path)) or not str(v) or not os.path.isfile(str(v)):
                continue
            (out.append((name, str(v))) if src == "DEFAULT_MAP" else typed.add(os.path.realpath(str(v))))
    return [(n, v) for n, v in out if os.path.realpath(v) not in typed]


def withheld(message: str, kind: str) -> str:
    """``message``, or a line that does not quote it when it names a file only ``--config`` gave: a TOML
    file someone else wrote must not make the tool print another local file's content."""
    for name, path in config_named_files():
        if path in message:
            flag = "--" + name.replace("_", "-")
            return (f"{path}: unusable as {flag} ({kind}); named by --config, not on the command line, so the "
                    f"details (which may quote the file) are not shown: give it as {flag} {path} to see them")
    return message


def guarded(fn):
    """Turn SensorlessError (and any unexpected error) into one line + non-zero exit; print
    every warning (ours, numpy's, torch's) on one line too."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        before_scipy()
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.showwarning = _show_warning
            _PRINTED.clear()
            try:
                with blas_threads_for_command():
                    return fn(*args, **kwargs)
            except typer.Exit:
                raise
            except SensorlessError as exc:
                _print_line("error:", "bold red", withheld(one_line(cli_words(exc)), type(exc).__name__))
                raise typer.Exit(2) from None
            except MemoryError as exc:  # a low memory limit (ulimit -v, a container): say so, in one line
                if os.environ.get("SENSORLESS_DEBUG"):
                    raise
                _print_line("error:", "bold red", withheld(
                    f"out of memory ({one_line(exc, 200) or 'MemoryError'}): raise the process's memory limit, or "
                    f"split or decimate the logs", "MemoryError"))
                raise typer.Exit(2) from None
            except Exception as exc:  # noqa: BLE001 - last line of defence for the user
                if os.environ.get("SENSORLESS_DEBUG"):
                    raise
                _print_line("internal error:", "bold red", withheld(
                    f"{type(exc).__name__}: {one_line(exc, 500)} (set SENSORLESS_DEBUG=1 for a traceback)",
                    type(exc).__name__))
                raise typer.Exit(3) from None

    return wrapper


@contextlib.contextmanager
def atomic_outdir(out: Path, force: bool, inputs: Iterable = ()) -> Iterator[Path]:
    """:func:`sensorless.io.atomic_output_dir` for a command: the manifest records the command
    and its options; ``inputs`` (files or folders the command reads) are never replaced."""
    from ..io import atomic_output_dir

    command = None
    ctx = current_context()
    if ctx is not None:
        command = {"name": " ".join(["sensorless", *ctx.command_path.split()[1:]]), "options": {
            k: v if isinstance(v, (str, int, float, bool, list, tuple, Path)) or v is None else str(v)
            for k, v in ctx.params.items()}}
    with atomic_output_dir(out, force, inputs=inputs, command=command) as tmp:
        yield tmp


def output_file(out: Path, inputs: Iterable = (), force: bool = False) -> Path:
    """Check a single-file ``--out``: not a directory or special file, not an input or inside an
    input folder, not an existing file unless ``--force``."""
    from ..io import check_output_file

    return check_output_file(out, inputs, force)


def path_inputs(*values) -> list:
    """The command-line values that are existing paths (logs, URDFs, data folders): never replaced."""
    out = []
    for v in values:
        for x in (v if isinstance(v, (list, tuple)) else [v]):
            if x is not None and str(x) and os.path.exists(str(x)):
                out.append(Path(str(x)))
    return out


def gains_option():
    return typer.Option(None, help="per-joint drive gains τ = K·i for logs of motor currents: a .json/.csv file "
                                   "(joint → gain), 'K1,K2,...' in column order, or 'joint=K,...'; "
                                   "'off' ignores a model's gains")


def resample_option(default: Optional[str] = "auto"):
    return typer.Option(default, help="auto (only if a time stamp repeats or a step is > 5 % off the median period) | off | "
                                      "RATE_HZ: interpolate onto a uniform grid" + ("" if default else "; default: the model's, else auto"))


def velocity_option(default: Optional[str] = "logged"):
    return typer.Option(default, help="logged (keep a logged v, v̇ = d/dt v) | from-q (v, v̇ from q)"
                        + ("" if default else "; default: the model's, else logged"))


def time_unit_option():
    return typer.Option(None, help=TIME_UNIT_HELP)


def max_gap_option(default: Optional[float] = None):
    return typer.Option(default, help="resampling refuses a time step over this many median periods (default 4)")


def model_preprocessing(model, **given) -> dict:
    """Preprocessing options for a log predicted with a model: each option given on the
    command line (not None) wins, else the model's (result.json settings.preprocessing, validated:
    :mod:`sensorless.identification.artifact`; ``model`` is a loaded ModelArtifact or a path).
    ``--columns`` carrying ':gain=' drops the model's gains; ``--gains off`` drops them too."""
    from ..data.prepare import PREPROCESSING_KEYS
    from ..identification.artifact import ModelArtifact, read_preprocessing

    from ..data.limits import current_options

    saved = model.preprocessing if isinstance(model, ModelArtifact) else read_preprocessing(model)
    given = {"angle_unit": current_options().get("angle_unit"), **given}  # --angle-unit (log_reading_options)
    out = {k: (given.get(k) if given.get(k) is not None else saved.get(k)) for k in PREPROCESSING_KEYS}
    if isinstance(given.get("columns"), str) and ":gain=" in given["columns"] and given.get("gains") is None:
        out["gains"] = None
    if isinstance(out["gains"], str) and out["gains"].strip().lower() in ("off", "none"):
        out["gains"] = None
    return out


def load_robot_arg(robot: str, lock: Optional[List[str]], floating: Optional[bool], passive: Optional[List[str]] = None):
    """:func:`sensorless.run.model.load_run_robot` with the command's ``--trust-xacro``, ``--package-path``
    (:func:`robot_source_options`) and ``--add-frame`` (:func:`~.frames.frame_options`)."""
    from ..run.model import load_run_robot

    source = _ROBOT_SOURCE.get()
    return load_run_robot(robot, lock or (), floating, passive or (), frames=ADDED_FRAMES.get(),
                          trust_xacro=source.get("trust_xacro", False), package_paths=source.get("package_paths", ()))


ADDED_FRAMES: "contextvars.ContextVar[tuple]" = contextvars.ContextVar("added_frames", default=())
_ROBOT_SOURCE: "contextvars.ContextVar[dict]" = contextvars.ContextVar("robot_source", default={})


def robot_source_options(fn):
    """Decorator: ``--trust-xacro`` and ``--package-path DIR`` (repeatable) for a command that loads
    a robot; :func:`load_robot_arg` reads them while the command runs."""

    @functools.wraps(fn)
    def run(*args, trust_xacro: bool = False, package_path: Optional[List[Path]] = None, **kwargs):
        token = _ROBOT_SOURCE.set({"trust_xacro": trust_xacro, "package_paths": tuple(package_path or ())})
        try:
            return fn(*args, **kwargs)
        finally:
            _ROBOT_SOURCE.reset(token)

    return add_options(ROBOT_SOURCE_OPTIONS)(run)


TRUST_XACRO_HELP = ("expand a .xacro robot file (it can run code on this machine: read it first); in a subprocess "
                    "limited to SENSORLESS_XACRO_TIMEOUT s (30) and SENSORLESS_XACRO_MEMORY_MB (1024)")
PACKAGE_PATH_HELP = ("folder the robot description may read meshes/includes from besides its own (package:// "
                     "looks here; repeatable; ROS_PACKAGE_PATH counts too)")
ROBOT_SOURCE_OPTIONS = {  # name -> (annotation, option factory)
    "trust_xacro": (bool, lambda: typer.Option(False, "--trust-xacro", help=TRUST_XACRO_HELP)),
    "package_path": (Optional[List[Path]], lambda: typer.Option(None, help=PACKAGE_PATH_HELP)),
}


def _robot_help() -> str:
    from ..robots.registry import ROBOTS

    code = "; ".join(f"{e.names[0]} ({e.description})" for e in ROBOTS if e.in_code)
    return ("URDF path, xacro file (only with --trust-xacro: it can run code), MJCF path, or a registered robot name: "
            f"example-robot-data's (e.g. panda, ur5, solo12) or built in code: {code}")


ROBOT_HELP = _robot_help()


# ---- the preprocessing options of commands that apply an identified model ------------------
_MODEL_DEFAULT = " (default: the model's)"
_PREPROCESSING_OPTIONS = {  # name -> (annotation, option factory)
    "columns": (Optional[str], lambda: typer.Option(None, help="column map, e.g. 'q=0:7;v=7:14;tau=14:21' or "
                                                              "'q=pos_{joint}'" + _MODEL_DEFAULT)),
    "rate": (Optional[float], lambda: typer.Option(None, help=RATE_HELP + _MODEL_DEFAULT)),
    "lowpass": (Optional[float], lambda: typer.Option(None, help="zero-phase low-pass cut-off [Hz]" + _MODEL_DEFAULT)),
    "savgol_window": (Optional[int], lambda: typer.Option(None, help="Savitzky-Golay window [samples] for v̇"
                                                                     + _MODEL_DEFAULT)),
    "gains": (Optional[str], lambda: gains_option()),
    "trim": (Optional[List[str]], lambda: trim_option()),
    "resample": (Optional[str], lambda: resample_option(None)),
    "velocity": (Optional[str], lambda: velocity_option(None)),
    "max_gap": (Optional[float], lambda: max_gap_option()),
    "time_unit": (Optional[TimeUnit], lambda: time_unit_option()),
    "base_velocity": (Optional[BaseVelocity], lambda: base_velocity_option(None)),
    "pose_max_gap": (Optional[float], lambda: pose_max_gap_option()),
}
MODEL_PREPROCESSING = tuple(_PREPROCESSING_OPTIONS)


def add_options(options: dict, *, into: Optional[str] = None, first: bool = False):
    """Decorator: the command gets the options ``options`` (name -> (annotation, option factory)),
    after its own (before them with ``first``). ``into``: they reach the command as one dict argument of that name;
    else by name (a parameter of the command with the same name, declared without default, is
    replaced by the shared option)."""
    import inspect

    def deco(fn):
        sig = inspect.signature(fn)
        own = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY) for p in sig.parameters.values()
               if p.name != into and p.name not in options]
        extra = [inspect.Parameter(n, inspect.Parameter.KEYWORD_ONLY, default=make(), annotation=ann)
                 for n, (ann, make) in options.items()]

        @functools.wraps(fn)
        def wrapper(*args, **kwargs):
            if into is not None:
                kwargs[into] = {n: kwargs.pop(n, None) for n in options}
            return fn(*args, **kwargs)

        wrapper.__signature__ = sig.replace(parameters=extra + own if first else own + extra)
        wrapper.__annotations__ = {**{k: v for k, v in getattr(fn, "__annotations__", {}).items() if k != into},
                                   **{n: ann for n, (ann, _) in options.items()}}
        return wrapper

    return deco


READING_OPTIONS = {
    "angle_unit": (Optional[AngleUnit], lambda: typer.Option(
        None, help="unit of the logged joint angles: rad | deg (q, v, v̇ of revolute joints converted from degrees; "
                   "recorded in result.json; default rad, or the model's)")),
    "joint_order": (Optional[JointOrder], lambda: typer.Option(
        None, help="names (default): a log's q columns are matched to the model by the joint names the log holds; "
                   "model: a log that names none of its columns follows the model's joint order (confirms it where "
                   "the file holds text arrays that may be its own names)")),
    "time_from": (Optional[TimeFrom], lambda: typer.Option(
        None, help="stamps (default): the log's time column; rate: the samples are uniform and the stamps are "
                   "arrival times (bursts after gaps): t = k / --rate, or k / their mean rate over the log")),
    "base_rpy": (bool, lambda: typer.Option(
        False, help="the logged base pose is x y z roll pitch yaw [rad] (extrinsic x-y-z: R = Rz(yaw) Ry(pitch) "
                    "Rx(roll)), e.g. two arrays --columns 'base_q=base_position,base_rpy', instead of x y z qx qy qz qw")),
    "max_log_memory": (Optional[str], lambda: typer.Option(
        None, help="memory a log may expand to when read and preprocessed, e.g. 8GiB (default: a quarter of the "
                   "available memory, or $SENSORLESS_MAX_LOG_MEMORY); a larger log is refused before reading")),
    "allow_hdf5_external": (bool, lambda: typer.Option(
        False, help="read HDF5 datasets stored in other files (external raw storage, virtual datasets)")),
    "accept_implausible_gains": (bool, lambda: typer.Option(
        False, help="accept --gains whose torques no robot model plus friction can produce (turns off this check only)")),
    "skip_bad_rows": (bool, lambda: typer.Option(
        False, help="drop corrupt rows at the start or end of a log (non-finite or absurd values, time running "
                    "backwards or repeating or off the clock, a last row cut short; at most 5 % of the rows or 20) "
                    "and isolated ones anywhere (at most 3 in a row, the clock continuing across them) with a "
                    "warning naming each; longer corruption in the middle stays an error")),
}


def log_reading_options(skip_bad: bool = True):
    """Decorator: ``--angle-unit``, ``--joint-order``, ``--time-from``, ``--base-rpy``, ``--max-log-memory``, ``--allow-hdf5-external``, ``--accept-implausible-gains``,
    ``--skip-bad-rows`` (and ``--skip-bad`` unless the command has its own), applied to every log the command reads
    (:func:`sensorless.data.limits.read_options`)."""
    options = dict(READING_OPTIONS)
    if skip_bad:
        options["skip_bad"] = (bool, lambda: typer.Option(
            False, help="read the rest of a ROS bag / MCAP file with corrupt chunks (a warning counts what was lost; "
                        "corrupt rows at a log's start or end: --skip-bad-rows)"))

    def deco(fn):
        @functools.wraps(fn)
        def run(*args, reading: dict, **kwargs):
            from ..data.limits import read_options

            with read_options(max_memory=reading["max_log_memory"], allow_external=reading["allow_hdf5_external"],
                              accept_implausible_gains=reading["accept_implausible_gains"],
                              skip_bad=reading.get("skip_bad"), skip_bad_rows=reading["skip_bad_rows"],
                              angle_unit=None if reading["angle_unit"] is None else str(reading["angle_unit"]),
                              joint_order=None if reading["joint_order"] is None else str(reading["joint_order"]),
                              time_from=None if reading["time_from"] is None else str(reading["time_from"]),
                              base_rpy=reading["base_rpy"] or None):
                return fn(*args, **kwargs)

        return add_options(options, into="reading")(run)

    return deco


def model_preprocessing_options(names: tuple[str, ...] = MODEL_PREPROCESSING):
    """Decorator: the command gets the options ``names`` (columns, rate, lowpass, ...; each
    defaulting to the model's own, result.json settings.preprocessing) in one ``prep`` dict
    argument instead of one parameter each; one definition for predict, monitor,
    estimate-force and payload."""
    return add_options({n: _PREPROCESSING_OPTIONS[n] for n in names}, into="prep")


def robot_option():
    return typer.Option(..., help=ROBOT_HELP)


def force_option():
    return typer.Option(False, help="replace --out if it exists")


def lock_option(help: str = "joints to lock (e.g. gripper fingers)"):
    return typer.Option(None, help=help)


def floating_base_option():
    return typer.Option(None, "--floating-base/--fixed-base")


def model_options(model: str = "result.json (or its directory) from `sensorless identify`", required: bool = True,
                  robot_required: bool = True):
    """Decorator: ``--robot`` and ``--model`` (an identified model, help ``model``; optional unless ``required``)
    as the first options; one definition for the commands that apply a model. Without ``robot_required``,
    ``--robot`` may be left out (a friction-only model from `sensorless friction` has no robot)."""
    robot = (str, robot_option) if robot_required else (Optional[str], lambda: typer.Option(
        None, help=ROBOT_HELP + "; not needed for a friction-only model (sensorless friction)"))
    ann, default = (Path, ...) if required else (Optional[Path], None)
    return add_options({"robot": robot, "model": (ann, lambda: typer.Option(default, help=model))}, first=True)


def model_logs(model, paths, robot, prep: dict, *, outliers: str = "error") -> tuple[list, dict]:
    """Logs to apply a model (a ModelArtifact, or a path) to, preprocessed as its training logs were:
    each option in ``prep`` given (not None) wins, else the model's (:func:`model_preprocessing`);
    ``prep["trim"]``: the ``--trim`` values (FILE= names checked against ``paths``).
    Returns (trajectories, the resolved options)."""
    opts = model_preprocessing(model, **{k: v for k, v in prep.items() if k != "trim"})
    trajs = load_logs(paths, robot, opts["columns"], opts["rate"], opts["lowpass"], opts["savgol_window"], 1,
                      gains=opts["gains"], trim=log_trims(prep.get("trim"), paths), resample=opts["resample"],
                      velocity=opts["velocity"], max_gap=opts["max_gap"], outliers=outliers, rest=opts.get("rest"),
                      time_unit=opts.get("time_unit"), base_velocity=opts.get("base_velocity"),
                      pose_max_gap=opts.get("pose_max_gap"), wrench_frames=opts.get("wrench_frames"),
                      angle_unit=opts.get("angle_unit"))
    return trajs, opts
