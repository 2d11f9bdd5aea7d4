"""Figures and console tables."""

from .html import render_html_report, write_html_report
from .plots import plot_torques
from .tables import metrics_table

__all__ = ["metrics_table", "plot_torques", "render_html_report", "write_html_report"]
