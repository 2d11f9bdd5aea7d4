"""The configuration of one identification run: frozen, typed, grouped, and its defaults are *the*
defaults (``sensorless identify`` builds its options from these fields).

:class:`RunConfig` holds four groups: :class:`LogsConfig` (files, columns, rate, time unit, trims,
preprocessing, outliers, reading limits), :class:`ModelConfig` (robot, joint terms, contacts,
passive joints, frames), :class:`SolverConfig` (method, γ and its search, regularisation,
ellipsoids, weights, prior, plausibility) and :class:`ExecutionConfig` (backend: scheduler, workers,
streaming; output: folder, figures). A field is named ``group.field`` in messages
(``solver.gamma``); the field names are unique across groups, so a flat table of options
(``{"gamma": "auto", "data": [...]}``, a TOML file, the command's options) maps onto it
(:meth:`RunConfig.from_options`). Each field's metadata carries its ``help`` and, where they differ
from ``--field-name``, its command-line ``flags``; ``choices`` lists the values a string field takes.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["RunConfig", "LogsConfig", "ModelConfig", "SolverConfig", "ExecutionConfig", "GROUPS", "config_fields"]


def _f(default: Any = None, help: str | None = None, *, flags: tuple[str, ...] = (), choices: tuple[str, ...] = (),
       required: bool = False, cli_only: bool = False):
    """A config field: ``help`` (None: the command's shared option of that name gives it), command-line
    ``flags`` (default ``--name``), ``choices``, ``required`` (no default: the run needs it),
    ``cli_only`` (consent or an override given on the command line only, never in a file: ``trust_xacro``,
    ``allow_hdf5_external``, ``force``, the ``accept_*`` overrides)."""
    meta = {"help": help, "flags": flags, "choices": choices, "required": required, "cli_only": cli_only}
    if isinstance(default, (list, tuple)):
        return field(default=tuple(default), metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class LogsConfig:
    """The logs and how they are read and preprocessed (``sensorless.data.load_log``)."""

    data: tuple[Path, ...] = _f((), "training log(s): <log formats> (the registry sensorless.data.formats; docs/logs.md); "
                                "several after one flag "
                                "(--data a.csv b.csv) or repeated", required=True)
    validate: tuple[Path, ...] = _f((), "held-out log(s) to report metrics on (several after one flag too)")
    columns: str | None = _f(None, "column map, e.g. 'q=0:7;v=7:14;tau=14:21' or 'q=pos_{joint}'")
    rate: float | None = _f(None, "sample rate [Hz] for logs without a time column; with --time-unit tick, the "
                            "controller's tick rate (ticks per second)")
    time_unit: str | None = _f(None, choices=("s", "ms", "us", "ns", "tick"))
    lowpass: float | None = _f(None, "zero-phase low-pass cut-off [Hz] before identification")
    savgol_window: int | None = _f(None, "Savitzky-Golay window: re-derive v̇ from the logged v (v and v̇ from q "
                                   "when v is not logged)")
    decimate: int = _f(1, "keep every n-th sample (after anti-alias filtering)")
    gains: str | None = _f(None)
    trim: tuple[str, ...] = _f(())
    resample: str = _f("auto")
    velocity: str = _f("logged", choices=("logged", "from-q"))
    max_gap: float | None = _f(None)
    base_velocity: str = _f("auto", choices=("auto", "from-pose", "logged"))
    pose_max_gap: float | None = _f(None)
    wrench_frame: tuple[str, ...] = _f(())
    imu_frame: str | None = _f(None, "model frame of the accelerometer ('imu_acc'): rotation and lever arm from the "
                               "model, on any body (e.g. imu_link)")
    outliers: str = _f("error", "gross outliers in a log (robust MAD test): error | drop (with a warning) | keep",
                       choices=("error", "drop", "keep"))
    rest: str = _f("auto", "auto: a joint whose logged |v| stays within 5 noise stds of 0 over the derivative window "
                   "is at rest, v = v̇ = 0 there (no friction chatter at rest; the model remembers it), unless it "
                   "drifts consistently (creeping: v = its drift) | off (docs/arm.md §7)", choices=("auto", "off"))
    skip_bad: bool = _f(False, "skip unreadable/invalid --data files (listed in result.json) instead of failing "
                        "(corrupt rows at a log's start or end: --skip-bad-rows)")
    skip_bad_rows: bool = _f(False)
    angle_unit: str | None = _f(None, choices=("rad", "deg"))
    joint_order: str | None = _f(None, choices=("names", "model"))
    time_from: str | None = _f(None, choices=("stamps", "rate"))
    base_rpy: bool = _f(False)
    max_log_memory: str | None = _f(None)
    allow_hdf5_external: bool = _f(False, cli_only=True)
    accept_implausible_gains: bool = _f(False, cli_only=True)


@dataclass(frozen=True)
class ModelConfig:
    """The robot and the model fitted to it: joint terms, friction law, contacts, passive joints, frames."""

    robot: str = _f("", required=True)
    lock: tuple[str, ...] = _f(())
    passive: tuple[str, ...] = _f((), "joint without an actuator (repeatable; e.g. a leg's vertical rail): no torque "
                                  "is logged for it (a 'tau' column may be absent or anything), its generalized force "
                                  "is 0 apart from its own friction (fv, fc, stribeck terms only); its equation is "
                                  "fitted, and with --contact-frames it is projected like a floating base's; kept in "
                                  "the model (settings.robot.passive)")
    floating_base: bool | None = _f(None)
    add_frame: tuple[str, ...] = _f(())
    trust_xacro: bool = _f(False, cli_only=True)
    package_path: tuple[Path, ...] = _f(())
    joint_terms: str = _f("fv,fc,stribeck,offset,armature",
                          "joint terms fv,fc,stribeck,offset,armature (and opt-in presliding, docs/arm.md §7) for "
                          "every joint, or per joint 'JOINT=fv,fc,offset;JOINT=fv;*=fv,fc' ('*': the joints not "
                          "listed, else none); a --passive joint keeps its friction terms only (dvrk_psm: drive set "
                          "'authors' (default) or 'motors')")
    coulomb_smoothing: str | float = _f("auto", "ε [rad/s] of the Coulomb term tanh(v/ε); 0 = sgn(v); auto: 3 × the "
                                        "joint's velocity noise, or a transition width fitted per joint where the "
                                        "data support it (BIC; docs/arm.md §7)")
    stribeck_velocity: str | float = _f("auto", "vs [rad/s] of the 'stribeck' term: a number, or auto (per joint, "
                                        "the best of a grid of candidates compressed in the same pass)")
    contact_frames: str | None = _f(None, "legged robots: comma-separated contact frames (feet); projects out the "
                                    "unknown contact forces, flags from the log's 'contact' columns or detected from "
                                    "foot height/speed")
    contact_dims: str | None = _f(None, "per contact frame 3 (point foot) or 6 (flat foot); default 3")
    contact_offset: float = _f(0.0, "radius [m] of spherical feet (contact point below the frame)")
    contact_mode: str = _f("projected", "projected (no force sensing) | wrench (log has contact_forces)",
                           choices=("projected", "wrench"))
    contact_rows: str = _f("auto", "wrench mode: base (6 floating-base rows; logs without joint torques) | all (+ "
                           "torque rows) | auto (base when the logs have no torques)", choices=("auto", "base", "all"))
    wrench_offset: str = _f("none", "wrench mode: constant wrench bias to identify: none | net | foot (world axes, per "
                            "foot) | sole (force in each sole frame)", choices=("none", "net", "foot", "sole"))
    offset_axes: str = _f("xy", "force axes of --wrench-offset (xyz adds the vertical one, confounded with m·g on "
                          "standing data)")


@dataclass(frozen=True)
class SolverConfig:
    """How the parameters are solved for, and what a fitted model must satisfy."""

    method: str = _f("lmi", "lmi: physically consistent, regularised toward the prior (the URDF); ols/wls: "
                     "unconstrained least squares; svd: minimum-norm truncated SVD", choices=("ols", "wls", "lmi", "svd"))
    prior: Path | None = _f(None, "lmi: URDF whose inertials are the prior (default: --robot's own)")
    regularization: str = _f("pullback", "lmi: regulariser toward the prior",
                             choices=("pullback", "entropic", "euclidean", "none"))
    gamma: str | float = _f("auto", "lmi: regularisation weight, or 'auto' (5-fold cross-validation)")
    gamma_search: str = _f("bracket", "--gamma auto: bracket (golden-section search on the γ grid, the whole grid when "
                           "its scores are not unimodal) | exhaustive (every γ of the grid) | closed-form (bracket; no "
                           "conic solve where no constraint binds: exact, may pick another γ than the solver's "
                           "scores)", choices=("bracket", "exhaustive", "closed-form"))
    ellipsoids: str = _f("auto", "lmi: bounding ellipsoids", choices=("auto", "kinematic", "none"))
    contain_prior: bool = _f(True, "lmi: grow each ellipsoid to contain any body near the prior (second moments ×4, "
                             "CoM within 7.5 cm); --no-contain-prior: geometry only")
    weights: str = _f("auto", "per-joint noise weighting, every method: auto (two-step: σ from an unweighted fit's "
                      "residual) | none | FILE (JSON {joint: σ} or CSV 'joint,σ' rows)")
    accept_implausible: bool = _f(False, "keep going when the identified model is implausible (a non-finite value, "
                                  "a body heavier than the whole prior robot, a CoM outside its body, a determined "
                                  "total mass > 50 % off the prior's); refused by default, naming the quantity. Turns "
                                  "off this check only", cli_only=True)
    accept_implausible_torques: bool = _f(False, "fit torque channels that look constant, dead, swapped, sign-flipped "
                                          "or > 100× off the prior model's scale; refused by default, naming the "
                                          "joint. Turns off this check only", cli_only=True)
    urdf_values: str = _f("prior", "model.urdf: prior (a body whose mass the data do not determine gets the prior's "
                          "mass, the identified dynamics unchanged) | regularised (the regularised values of "
                          "result.json)")


@dataclass(frozen=True)
class ExecutionConfig:
    """Where the equations are compressed (this process, streamed, or a Dask cluster) and what is written."""

    scheduler: str | None = _f(None, "compress on Dask: 'local' (a LocalCluster on this machine) or a scheduler "
                               "address tcp://HOST:PORT; workers read the --data files themselves (see docs/fleet.md)")
    workers: int | None = _f(None, "--scheduler local: worker processes (default: one per core); an address: wait "
                             "until this many workers are connected")
    stream: bool | None = _f(None, "one long training log read and compressed chunk by chunk in one pass (bounded "
                             "memory; docs/logs.md): default when it applies to a log of >= 50,000 samples; "
                             "--stream: at any length; --no-stream: the whole log in memory",
                             flags=("--stream/--no-stream",))
    plot: bool = _f(True, "write torques.png (a decimated window of the first held-out log, else of the first "
                    "training log, with residuals; torques_<limb>.png per limb for a robot with several) and "
                    "friction.png", flags=("--plot/--no-plot",))
    out: Path | None = _f(None, "output directory (written atomically)", required=True)
    force: bool = _f(False, cli_only=True)


#: group name -> its dataclass, in the order of RunConfig's fields
GROUPS = {"logs": LogsConfig, "model": ModelConfig, "solver": SolverConfig, "execution": ExecutionConfig}


def config_fields() -> dict[str, tuple[str, dataclasses.Field]]:
    """``{field name: (group, dataclasses.Field)}`` over every group (names are unique)."""
    return {f.name: (g, f) for g, cls in GROUPS.items() for f in dataclasses.fields(cls)}


def _plain(v):
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, Path):
        return str(v)
    return v if isinstance(v, (str, int, float, bool)) or v is None else str(v)


@dataclass(frozen=True)
class RunConfig:
    """One identification run: ``RunConfig(logs=LogsConfig(data=("a.npz",)), model=ModelConfig(robot="ur5"))``,
    or flat: ``RunConfig.from_options(robot="ur5", data=["a.npz"])``. ``source``: the TOML file it was read
    from, if any (recorded in result.json ``settings.config.file``)."""

    logs: LogsConfig = field(default_factory=LogsConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    solver: SolverConfig = field(default_factory=SolverConfig)
    execution: ExecutionConfig = field(default_factory=ExecutionConfig)
    source: str | None = None

    @classmethod
    def from_options(cls, source: str | None = None, **options) -> "RunConfig":
        """The config with each named field set (``gamma="auto"``, ``data=["a.npz"]``); a list becomes a
        tuple, an unknown name is a TypeError naming it."""
        table = config_fields()
        unknown = sorted(k for k in options if k not in table)
        if unknown:
            raise TypeError(f"unknown run option(s) {', '.join(unknown)}")
        groups: dict[str, dict] = {g: {} for g in GROUPS}
        for k, v in options.items():
            groups[table[k][0]][k] = tuple(v) if isinstance(v, list) else v
        return cls(**{g: GROUPS[g](**kw) for g, kw in groups.items()}, source=source)

    def replace(self, **options) -> "RunConfig":
        """A copy with the named fields (flat names, as :meth:`from_options`) changed."""
        return RunConfig.from_options(self.source, **{**self.options(plain=False), **options})

    def options(self, plain: bool = True) -> dict:
        """``{field name: value}`` over every group (JSON-ready with ``plain``: paths as strings, tuples as lists)."""
        out = {f.name: getattr(getattr(self, g), f.name) for g, cls in GROUPS.items() for f in dataclasses.fields(cls)}
        return {k: _plain(v) for k, v in out.items()} if plain else out
