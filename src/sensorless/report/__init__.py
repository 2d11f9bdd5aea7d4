"""Figures and console tables."""

from typing import TYPE_CHECKING

from ..lazy import lazy_exports
from .friction_plot import plot_friction
from .html import render_html_report, write_html_report
from .plots import plot_torques, plot_torques_by_limb, torque_figure
from .rows import limb_groups
from .tables import metrics_table

# the other commands' figures are imported on first use (PEP 562)
__getattr__, __dir__ = lazy_exports(globals(), {"force_figure": ".force_plot"})

if TYPE_CHECKING:
    from .force_plot import force_figure

__all__ = ["force_figure", "limb_groups", "metrics_table", "plot_friction", "plot_torques", "plot_torques_by_limb",
           "render_html_report", "torque_figure", "write_html_report"]
