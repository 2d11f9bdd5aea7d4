"""Contiguous time blocks of one or several logs: the folds of blocked cross-validation.

Neighbouring samples of a log are correlated (filtered signals, slow drifts), so a sample left out
next to its neighbours in the fit is not held out. :func:`blocked_folds` cuts the logs, concatenated
in order, into ``n_folds`` contiguous pieces of (nearly) equal length: fold f of sample i is the
piece its position in the concatenation falls in. The γ cross-validation and the blocked held-out
error of ``identify`` use it; so can any blocked resampling.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["blocked_folds"]


def blocked_folds(lengths: Sequence[int], n_folds: int) -> list[np.ndarray]:
    """Per log (of ``lengths`` samples, in order), the fold 0 … n_folds − 1 of each sample: the
    concatenation cut into ``n_folds`` contiguous, (nearly) equal pieces."""
    total = int(sum(lengths))
    if n_folds < 1 or total < n_folds:
        raise ValueError(f"cannot cut {total} samples into {n_folds} contiguous blocks")
    edges = np.linspace(0, total, n_folds + 1).round().astype(int)
    start, out = 0, []
    for n in lengths:
        out.append(np.searchsorted(edges, start + np.arange(int(n)), side="right") - 1)
        start += int(n)
    return out
