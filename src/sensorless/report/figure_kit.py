"""What every figure shares: an Agg figure outside pyplot, atomic saving, decimation of long
logs, shaded time intervals and one legend above the axes.

Figures are :class:`matplotlib.figure.Figure` objects on an Agg canvas, never pyplot's global
state: a plotting function returns its figure (a test inspects its axes, labels and artists;
the HTML report embeds it) and is collected like any object.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

__all__ = ["TEXT_RC", "envelope_indices", "figure_legend", "in_view_locator", "new_figure", "paired_axes", "runs_of",
           "render_png", "save_figure", "shade_intervals", "stride_indices", "text_style"]

DPI = 110
#: Text rendered without FreeType's hinting: ~10 % less per figure of ~80 labels, no visible change at
#: 110 dpi. Set around each drawing (:func:`text_style`), so matplotlib's settings elsewhere stay the user's.
TEXT_RC = {"text.hinting": "no_hinting"}


def new_figure(width: float, height: float):
    """A ``width`` × ``height`` inch figure on an Agg canvas (no pyplot, no display)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def text_style():
    """A context in which figures are drawn with :data:`TEXT_RC` (every drawing of these figures: the
    text metrics matplotlib caches depend on it)."""
    import matplotlib

    return matplotlib.rc_context(TEXT_RC)


def render_png(fig, fh) -> None:
    """Draw ``fig`` as PNG into the binary file ``fh``. zlib level 3 instead of PIL's 6: ~20 ms less per
    figure for ~1 % more bytes."""
    with text_style():
        fig.savefig(fh, format="png", dpi=DPI, pil_kwargs={"compress_level": 3})


def save_figure(fig, path: "str | Path") -> Path:
    """Write ``fig`` as PNG (:func:`render_png`) to ``path`` atomically (a reader sees the old file or the new one)."""
    from ..io import atomic_open

    with atomic_open(path, "wb") as fh:
        render_png(fig, fh)
    return Path(path)


def paired_axes(fig, n: int, ncols: int, *, left: float, right: float, top: float, bottom: float, wspace: float,
                ratios=(2.0, 1.0), gap: float = 0.45, share_all: bool = True, by_rows: bool = False):
    """Axes pairs (upper, lower: a signal and its residual) for ``n`` rows in ``ncols`` columns (down the
    first column first, or along the first row with ``by_rows``); margins and the ``gap`` between rows in
    inches. Each pair shares x; with ``share_all`` every pair shares the first one's. Returns (pairs,
    rows per column)."""
    w, h = fig.get_figwidth(), fig.get_figheight()
    nr = int(np.ceil(n / ncols))
    cell = (h - top - bottom - (nr - 1) * gap) / nr
    outer = fig.add_gridspec(nr, ncols, left=left / w, right=1 - right / w, top=1 - top / h, bottom=bottom / h,
                             wspace=wspace, hspace=gap / cell)
    pairs, first = [], None
    for k in range(n):
        inner = outer[divmod(k, ncols) if by_rows else (k % nr, k // nr)].subgridspec(2, 1, height_ratios=ratios, hspace=0.08)
        a = fig.add_subplot(inner[0], sharex=first if share_all else None)
        first = first or a
        b = fig.add_subplot(inner[1], sharex=a)
        # the lower panel carries the shared x axis: the upper one draws none (no ticks built: ~10 % of a figure)
        a.xaxis.set_visible(False)
        a.tick_params(labelsize=7)
        b.tick_params(labelsize=7)
        for ax in (a, b):  # few ticks on small panels: each tick is a handful of artists to build and draw
            ax.yaxis.set_major_locator(in_view_locator(nbins=4))
        a.xaxis.set_major_locator(in_view_locator(nbins=6))
        pairs.append((a, b))
    return pairs, nr


def in_view_locator(nbins: int):
    """matplotlib's ``MaxNLocator(nbins)`` without the locations outside the axis' view: matplotlib
    builds a tick (five artists, ~1 ms) for every location its locator gives, drawn or not, and
    ``MaxNLocator`` gives one beyond each end. The ticks drawn are the same; a figure of 12 panels
    draws ~8 % sooner."""
    return _in_view_locator_class()(nbins=nbins)


@functools.cache
def _in_view_locator_class():
    from matplotlib.ticker import MaxNLocator

    class InViewLocator(MaxNLocator):
        def __call__(self):
            locs = super().__call__()
            lo, hi = sorted(self.axis.get_view_interval())
            tol = 1e-10 * max(hi - lo, np.finfo(float).tiny)
            return locs[(locs >= lo - tol) & (locs <= hi + tol)]

    return InViewLocator


def stride_indices(n: int, max_points: int) -> np.ndarray:
    """Every k-th of ``n`` samples, at most ``max_points`` of them (smooth signals)."""
    return np.arange(0, n, max(1, int(np.ceil(n / max(1, max_points)))))


def envelope_indices(y: np.ndarray, max_points: int) -> np.ndarray:
    """Sorted sample indices that keep the shape of a long signal ``y`` (N,) or (N, m) in about
    ``max_points`` points: in each of ``max_points // 2`` equal buckets, the samples of the
    minimum and the maximum of every column (NaN ignored), so a short peak (a contact, a
    spike) survives decimation; the first and last samples are kept."""
    y = np.asarray(y, float)
    y = y[:, None] if y.ndim == 1 else y
    n = y.shape[0]
    if n <= max_points:
        return np.arange(n)
    buckets = max(1, max_points // (2 * y.shape[1]))
    size = int(np.ceil(n / buckets))
    pad = buckets * size - n
    keep = [np.array([0, n - 1])]
    for col in y.T:
        z = np.concatenate([col, np.full(pad, np.nan)]).reshape(buckets, size)
        finite = np.isfinite(z)
        lo = np.where(finite, z, np.inf).argmin(axis=1)
        hi = np.where(finite, z, -np.inf).argmax(axis=1)
        base = np.arange(buckets) * size
        keep += [base + lo, base + hi]
    idx = np.unique(np.concatenate(keep))
    return idx[idx < n]


def shade_intervals(ax, spans: Iterable[tuple[float, float]], *, color: str, alpha: float = 0.25, label: str | None = None,
                    gid: str | None = None, zorder: float = 0.5):
    """One collection of vertical bands over the whole height of ``ax``, one per (start, end) in data
    x; ``gid`` names it (a test finds it by ``get_gid``). Returns the collection (None if no span)."""
    from matplotlib.collections import PolyCollection

    spans = [(float(a), float(b)) for a, b in spans]
    if not spans:
        return None
    verts = [[(a, 0.0), (a, 1.0), (b, 1.0), (b, 0.0)] for a, b in spans]
    coll = PolyCollection(verts, transform=ax.get_xaxis_transform(), facecolors=color, edgecolors="none",
                          alpha=alpha, label=label, zorder=zorder)
    coll.set_gid(gid)
    ax.add_collection(coll, autolim=False)
    return coll


def runs_of(flag: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in ``flag``."""
    f = np.concatenate([[False], np.asarray(flag, bool), [False]])
    d = np.diff(f.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1))


def figure_legend(fig, handles: Sequence, labels: Sequence[str], top_in: float, *, ncol: int | None = None, **kw):
    """One legend for the whole figure, centred above the axes (``top_in`` inches below the top edge),
    so it never covers data."""
    h = fig.get_figheight()
    return fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 1 - top_in / h),
                      ncol=ncol or min(len(labels), 6), fontsize=8, frameon=False, **kw)
