"""Shared option vocabulary of the commands: choices (enums, listed in ``--help``) and
``--config run.toml``.

The choice enums are :class:`enum.StrEnum`: a value compares, hashes and formats as its
string, so the library receives plain strings. Their members mirror the library's own
tuples (``identification.METHODS``, ``data.outliers.OUTLIER_MODES``, ...; a test checks),
written out here so that ``--help`` does not import the solvers.
"""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Optional

import typer

from ..errors import OptionError

__all__ = ["Method", "Regularization", "GammaSearch", "Ellipsoids", "Outliers", "Velocity", "BaseVelocity", "ContactMode", "ContactRows",
           "WrenchOffset", "Rest", "Criterion", "ForceReference", "PayloadMode", "Align", "ALIGN_HELP",
           "LinearMethod", "PsmModel", "Training", "Acceleration", "TauLog", "TimeUnit", "AngleUnit", "JointOrder", "TimeFrom", "FrictionState", "config_option", "check_config", "config_error"]


def _choices(name: str, values: tuple[str, ...]) -> type[StrEnum]:
    return StrEnum(name, {v.replace("-", "_"): v for v in values})


Method = _choices("Method", ("ols", "wls", "lmi", "svd"))
Regularization = _choices("Regularization", ("pullback", "entropic", "euclidean", "none"))
GammaSearch = _choices("GammaSearch", ("bracket", "exhaustive", "closed-form"))
Ellipsoids = _choices("Ellipsoids", ("auto", "kinematic", "none"))
Outliers = _choices("Outliers", ("error", "drop", "keep"))
Velocity = _choices("Velocity", ("logged", "from-q"))
BaseVelocity = _choices("BaseVelocity", ("auto", "from-pose", "logged"))
ContactMode = _choices("ContactMode", ("projected", "wrench"))
ContactRows = _choices("ContactRows", ("auto", "base", "all"))
WrenchOffset = _choices("WrenchOffset", ("none", "net", "foot", "sole"))
Rest = _choices("Rest", ("auto", "off"))
Criterion = _choices("Criterion", ("cond", "dopt"))
ForceReference = _choices("ForceReference", ("local", "world", "local_world_aligned"))
PayloadMode = _choices("PayloadMode", ("auto", "full", "com", "mass"))
Align = _choices("Align", ("auto", "time", "rows"))
ALIGN_HELP = ("pairing of the two runs: auto (measure the lag between them from the positions; by time, or row by row "
              "when both share one time grid and the lag is under 5 % of a sample) | time (the reference run "
              "interpolated at the other's times shifted by the lag; for runs started at different instants) | rows "
              "(row by row, same length)")
LinearMethod = _choices("LinearMethod", ("ols", "wls"))
PsmModel = _choices("PsmModel", ("ols", "wls", "lmi"))
Training = _choices("Training", ("rich", "stance"))
Acceleration = _choices("Acceleration", ("simulator", "logged", "savgol", "savgol_imu", "none"))
TauLog = _choices("TauLog", ("sample", "mean"))
TimeUnit = _choices("TimeUnit", ("s", "ms", "us", "ns", "tick"))
AngleUnit = _choices("AngleUnit", ("rad", "deg"))
JointOrder = _choices("JointOrder", ("names", "model"))
TimeFrom = _choices("TimeFrom", ("stamps", "rate"))
FrictionState = _choices("FrictionState", ("auto", "on", "off"))
TIME_UNIT_HELP = ("unit of the logs' time column when it is not seconds: ms, us, ns, or tick (a controller's tick "
                  "counter, with --rate HZ); epoch stamps in ms/us/ns are recognised without it, a tick column is "
                  "refused without it (docs/logs.md)")
RATE_HELP = ("sample rate [Hz] for logs without a time column; with --time-unit tick, the controller's tick rate "
             "(ticks per second)")

_CONFIG_ERROR = "sensorless_config_error"


def _load_config(ctx, param, value: Optional[Path]) -> Optional[Path]:
    """Eager callback: the file's keys (:func:`sensorless.run.toml.read_run_toml`) become the command's
    defaults (``ctx.default_map``), so options on the command line win and values are converted like
    typed ones. A problem is kept for :func:`check_config` (raised inside the command, as one line)."""
    if value is None or ctx.resilient_parsing:
        return value
    from ..errors import SensorlessError
    from ..run.config import config_fields
    from ..run.toml import consent_refused, read_run_toml

    try:
        table = read_run_toml(value, keep_consent=True)
    except SensorlessError as exc:
        ctx.meta[_CONFIG_ERROR] = f"--config {exc}"
        return value
    fields = config_fields()
    consent = [k for k in table if k in fields and fields[k][1].metadata["cli_only"]]
    if consent:  # refused inside the command, the file's other keys applied (no usage error first)
        ctx.meta[_CONFIG_ERROR] = f"--config {consent_refused(value, consent)}"
        table = {k: v for k, v in table.items() if k not in consent}
    names = {p.name for p in ctx.command.params if p.name != "config"}
    unknown = sorted(k for k in table if k not in names)
    if unknown:
        ctx.meta[_CONFIG_ERROR] = f"--config {value}: {', '.join(unknown)} not options of this command"
        return value
    ctx.default_map = {**(ctx.default_map or {}), **table}
    return value


def config_option():
    return typer.Option(None, "--config", is_eager=True, callback=_load_config, exists=False,
                        help="TOML file whose keys are this command's options (method = \"lmi\", data = [\"a.csv\"], "
                             "savgol_window = 21 ...); options on the command line override it; the resolved "
                             "options are saved in result.json settings.config")


def current_context():
    """The running command's click context (typer ≥ 0.2x vendors click as ``typer._click``)."""
    try:
        from typer.main import get_current_context
    except ImportError:  # pragma: no cover - older typer on plain click
        from click import get_current_context
    return get_current_context(silent=True)


def config_error(ctx) -> str | None:
    """The problem :func:`_load_config` found in ``--config`` of the command ``ctx``, or None (a usage
    error such as a missing ``--data`` is then only its consequence)."""
    return (getattr(ctx, "meta", None) or {}).get(_CONFIG_ERROR)


def check_config() -> None:
    """Raise the problem :func:`_load_config` found in ``--config`` (OptionError, one line)."""
    ctx = current_context()
    if ctx is not None and ctx.meta.get(_CONFIG_ERROR):
        raise OptionError(ctx.meta[_CONFIG_ERROR])
