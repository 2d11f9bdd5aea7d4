"""One identification run as a library call: a frozen :class:`RunConfig` (logs, model, solver,
execution; its defaults are ``sensorless identify``'s) and :func:`identify_run`, which returns a
:class:`Run` to save as a model folder::

    from sensorless.run import RunConfig, identify_run
    run = identify_run(RunConfig.from_options(robot="ur5", data=["train.npz"]))
    run.save("ur5_model")

The same file the command reads: :func:`run_config_from_toml`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

_EXPORTS = {
    **dict.fromkeys(["RunConfig", "LogsConfig", "ModelConfig", "SolverConfig", "ExecutionConfig"], ".config"),
    **dict.fromkeys(["Run", "identify_run"], ".pipeline"),
    "run_config_from_toml": ".toml",
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:
    from .config import ExecutionConfig, LogsConfig, ModelConfig, RunConfig, SolverConfig
    from .pipeline import Run, identify_run
    from .toml import run_config_from_toml

__all__ = ["RunConfig", "LogsConfig", "ModelConfig", "SolverConfig", "ExecutionConfig", "Run", "identify_run",
           "run_config_from_toml"]
