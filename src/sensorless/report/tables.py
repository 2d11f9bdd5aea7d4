"""Rich console tables of per-joint metrics."""

from __future__ import annotations

import numpy as np

from rich.table import Table

from typing import TYPE_CHECKING
from rich.markup import escape

if TYPE_CHECKING:  # the figures' child process imports this package: no identification stack
    from ..identification.metrics import TorqueMetrics

__all__ = ["metrics_table"]


def metrics_table(title: str, columns: dict[str, TorqueMetrics], field: str = "nrmse") -> Table:
    """One row per joint, one column per model; ``field`` is rmse, nrmse (shown in %) or rel_rms."""
    pct = field in ("nrmse", "rel_rms")
    table = Table(title=f"{escape(title)} — {field}{' [%]' if pct else ''}")
    table.add_column("joint")
    for name in columns:
        table.add_column(escape(name), justify="right")
    first = next(iter(columns.values()))
    static = np.zeros(len(first.joints), bool) if first.static is None or field != "nrmse" else first.static
    for j, joint in enumerate(first.joints):
        row = [escape(joint) + (" (at rest)" if static[j] else "")]  # a name may hold "[/]"
        for m in columns.values():
            v = getattr(m, field)[j]
            if static[j]:  # the range is noise: RMSE and bias in N·m instead (metrics module docstring)
                row.append(f"{m.rmse[j]:.3g} N·m rms, bias {m.bias[j]:+.3g}" if m.bias is not None else "—")
            else:
                row.append(f"{100 * v:.2f}" if pct else f"{v:.4g}")
        table.add_row(*row)
    means = []
    for m in columns.values():
        vals = getattr(m, field)[~static]
        means.append("—" if not vals.size else f"{100 * vals.mean():.2f}" if pct else f"{vals.mean():.4g}")
    table.add_row("mean" + (" (moving joints)" if static.any() else ""), *means, style="bold")
    if static.any():
        table.caption = "at rest: " + first.STATIC_NOTE + "; RMSE and bias [N·m] shown instead"
    return table
