"""What ``sensorless predict`` draws: measured against predicted effort with the residual, per joint
(``<out>.png``), and a small self-contained page with the metrics and the figure (``<out>.html``)."""

from __future__ import annotations

import base64
from pathlib import Path

import numpy as np

from ..io import atomic_write_text
from .figure_kit import save_figure
from .html import metrics_html, page
from .html_format import esc
from .plots import torque_figure

__all__ = ["write_predict_report"]


def write_predict_report(png: "Path | None", html: Path, *, t: np.ndarray, measured: "np.ndarray | None",
                         predicted: np.ndarray, rows: list[str], robot, metrics: "dict | None", model_label: str,
                         log: str, notes: list[str] = ()) -> None:
    """Draw ``png`` (None: no measured effort, nothing to compare) and write ``html`` (module docstring);
    ``metrics``: a ``TorqueMetrics.to_dict()``; ``notes``: the warnings of the run, each shown."""
    parts = [f"<h1>sensorless predict: {esc(Path(log).name)}</h1>",
             f"<p>model: {esc(model_label)}<br>log: <code>{esc(log)}</code>, {len(t)} samples, "
             f"{float(t[-1] - t[0]) if len(t) else 0.0:.3g} s</p>"]
    if notes:
        parts.append("<h2>Warnings</h2>" + "".join(f"<div class=warn>{esc(n)}</div>" for n in notes))
    if metrics is not None:
        parts.append("<h2>Metrics</h2>" + metrics_html({"model": metrics}))
    else:
        parts.append("<p>The log has no measured effort: predictions only (no metrics, no figure).</p>")
    if png is not None and measured is not None:
        fig = torque_figure(t, measured, {"model": predicted}, rows, robot=robot,
                            title=f"{Path(log).name}: measured and predicted, residual below")
        save_figure(fig, png)
        b64 = base64.b64encode(Path(png).read_bytes()).decode("ascii")
        parts.append(f"<h2>Figure</h2><div class=fig><img alt='{esc(Path(png).name)}' "
                     f"src='data:image/png;base64,{b64}'></div>")
    atomic_write_text(html, page(f"predict {Path(log).name}", parts))
