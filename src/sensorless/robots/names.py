"""Names of the robots authored in code, importable without building them (CLI start-up)."""

from __future__ import annotations

__all__ = ["PSM_NAMES"]

PSM_NAMES = ("dvrk_psm", "dvrk-psm", "psm")
"""Names the command line accepts for the PSM model (``--robot dvrk_psm``)."""
