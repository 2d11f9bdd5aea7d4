"""Figures and console tables.

The names below are imported on first use (PEP 562): the figure process
(:mod:`.plot_process`) starts without the HTML report's and the console tables' modules (rich).
"""

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(globals(), {
    "force_figure": ".force_plot", "plot_friction": ".friction_plot", "limb_groups": ".rows",
    **dict.fromkeys(["render_html_report", "write_html_report"], ".html"),
    **dict.fromkeys(["plot_torques", "plot_torques_by_limb", "torque_figure"], ".plots"),
    "metrics_table": ".tables",
})

if TYPE_CHECKING:
    from .force_plot import force_figure
    from .friction_plot import plot_friction
    from .html import render_html_report, write_html_report
    from .plots import plot_torques, plot_torques_by_limb, torque_figure
    from .rows import limb_groups
    from .tables import metrics_table

__all__ = ["force_figure", "limb_groups", "metrics_table", "plot_friction", "plot_torques", "plot_torques_by_limb",
           "render_html_report", "torque_figure", "write_html_report"]
