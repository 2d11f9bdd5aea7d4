"""Figures and console tables."""

from .friction_plot import plot_friction
from .html import render_html_report, write_html_report
from .plots import plot_torques
from .tables import metrics_table

__all__ = ["metrics_table", "plot_friction", "plot_torques", "render_html_report", "write_html_report"]
