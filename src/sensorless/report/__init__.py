"""Figures and console tables."""

from typing import TYPE_CHECKING

from ..lazy import lazy_exports
from .friction_plot import plot_friction
from .html import render_html_report, write_html_report
from .plots import plot_torques, plot_torques_by_limb, torque_figure
from .rows import limb_groups
from .tables import metrics_table

# the other commands' figures are imported on first use (PEP 562)
__getattr__, __dir__ = lazy_exports(globals(), {
    **dict.fromkeys(["excitation_figure", "plot_excitation"], ".excitation_plot"),
    **dict.fromkeys(["force_figure", "plot_force"], ".force_plot"),
    **dict.fromkeys(["monitor_figure", "plot_monitor"], ".monitor_plot"),
})

if TYPE_CHECKING:
    from .excitation_plot import excitation_figure, plot_excitation
    from .force_plot import force_figure, plot_force
    from .monitor_plot import monitor_figure, plot_monitor

__all__ = ["excitation_figure", "force_figure", "limb_groups", "metrics_table", "monitor_figure", "plot_excitation",
           "plot_force", "plot_friction", "plot_monitor", "plot_torques", "plot_torques_by_limb", "render_html_report",
           "torque_figure", "write_html_report"]
