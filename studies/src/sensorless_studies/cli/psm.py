"""`sensorless experiment psm-identify`: the dVRK PSM held-out identification
(:mod:`sensorless_studies.experiments.psm_identification`)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import typer

from sensorless.errors import OptionError
from sensorless.cli.common import atomic_outdir, guarded, path_inputs, force_option
from sensorless.cli.console import console
from sensorless.cli.options import PsmModel
from sensorless.cli.progress import progress_bars

from .common import experiment_app



@experiment_app.command("psm-identify")
@guarded
def psm_identify(
    out: Path = typer.Option(..., help="output directory (written atomically): result.json (loadable by predict, "
                                       "estimate-force, payload), drive_terms.json, psm_identification.json"),
    data: Optional[Path] = typer.Option(None, help="folder of the WPI dVRK data set (the one holding data/psm/...)"),
    train: Optional[Path] = typer.Option(None, help="training log (header-less CSV: q, q̇, effort × 7, 200 Hz)"),
    test: Optional[Path] = typer.Option(None, help="held-out log, same format"),
    params: Optional[Path] = typer.Option(None, help="optional: the authors' params.json, for comparison"),
    save: Optional[PsmModel] = typer.Option(None, help="which model result.json holds: ols | wls | lmi (default: lmi "
                                                       "with --lmi, else ols)"),
    cutoff: float = typer.Option(5.4, help="zero-phase low-pass cut-off [Hz] on q, q̇ and effort"),
    smoothing: str = typer.Option("cv", help="Coulomb smoothing ε [rad/s], or 'cv' (3-fold cross-validation on the "
                                             "training log; slow)"),
    lmi: bool = typer.Option(False, help="also solve the physically consistent (LMI) problem"),
    force: bool = force_option(),
) -> None:
    """Identify the PSM on --train (or one_results), predict --test (or two_results); compare with
    the published parameters when given. The same as `sensorless identify --robot dvrk_psm --columns
    'q=0:7;v=7:14;tau=14:21' --rate 200 --lowpass 5.4`, plus Coulomb smoothing chosen by cross-validation."""
    from rich.table import Table

    from sensorless.io import write_json_atomic
    from ..experiments.psm_identification import psm_identification_study
    from sensorless.identification.artifact import save_model_folder

    save = save or (PsmModel.lmi if lmi else PsmModel.ols)  # --lmi: the physically consistent model is the one kept
    if data is None and (train is None or test is None):
        raise OptionError("give --data (the WPI folder) or both --train and --test")
    if smoothing != "cv":
        try:
            smoothing = float(smoothing)
            if not (math.isfinite(smoothing) and smoothing >= 0):
                raise ValueError
        except ValueError:
            raise OptionError(f"--smoothing must be a number or 'cv', got '{smoothing}'") from None
    with atomic_outdir(out, force, inputs=path_inputs(data, train, test, params)) as tmp:
        results: dict = {}
        with progress_bars() as bars:
            bars.step("identifying the PSM (smoothing by cross-validation on the training log)")
            report = psm_identification_study(
                data, train=train, test=test, params=params, results=results, cutoff_hz=cutoff, smoothing=smoothing,
                lmi={"ellipsoids": False, "regularization": None, "gamma": 0.0} if (lmi or save == "lmi") else None,
            )
        write_json_atomic(report, tmp / "psm_identification.json")
        result = results[save]
        result.settings.update({
            "data": [report["settings"]["train"]], "validate": [report["settings"]["test"]],
            "preprocessing": {"columns": {"q": "0:7", "v": "7:14", "tau": "14:21"}, "rate": 200.0, "lowpass": cutoff,
                              "velocity": "logged", "savgol_window": None, "resample": None, "gains": None,
                              "max_gap": None},
        })
        doc = result.to_dict()
        doc["validation"] = {report["settings"]["test"]: report["identified"][save]}
        save_model_folder(tmp, result, doc)
    table = Table(title=f"held-out NRMSE (RMSE / range), ε = {report['settings']['coulomb_smoothing']:g}")
    table.add_column("model")
    for c in report["coordinates"]:
        table.add_column(c, justify="right")
    rows = {k.upper(): v for k, v in report["identified"].items()}
    if "published" in report:
        rows["published"] = report["published"]
    for name, entry in rows.items():
        table.add_row(name, *(f"{entry['test_nrmse'][c]:.4g}" for c in report["coordinates"]))
    console.print(table)
    console.print(f"wrote {out}/ (result.json: the {save.upper()} model)")
