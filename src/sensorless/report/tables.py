"""Rich console tables of per-joint metrics."""

from __future__ import annotations

from rich.table import Table

from ..identification.metrics import TorqueMetrics

__all__ = ["metrics_table"]


def metrics_table(title: str, columns: dict[str, TorqueMetrics], field: str = "nrmse") -> Table:
    """One row per joint, one column per model; ``field`` is rmse, nrmse (shown in %) or rel_rms."""
    pct = field in ("nrmse", "rel_rms")
    table = Table(title=f"{title} — {field}{' [%]' if pct else ''}")
    table.add_column("joint")
    for name in columns:
        table.add_column(name, justify="right")
    first = next(iter(columns.values()))
    for j, joint in enumerate(first.joints):
        row = [joint]
        for m in columns.values():
            v = getattr(m, field)[j]
            row.append(f"{100 * v:.2f}" if pct else f"{v:.4g}")
        table.add_row(*row)
    means = [f"{100 * getattr(m, field).mean():.2f}" if pct else f"{getattr(m, field).mean():.4g}" for m in columns.values()]
    table.add_row("mean", *means, style="bold")
    return table
