"""RowMajorFold (the streamed pass's fold of row-major chunks) gives fold_chunk's equations: per fold, with
the equations left out of the fit zeroed and tracked apart, across chunk boundaries and fold runs, and
their sum is the dense NormalEquations.add of the assembled regressor."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from sensorless.regressor.normal_equations import NormalEquations, RowMajorFold, fold_chunk

ROWS, NB, NT = 4, 20, 3
TERM_ROWS = np.array([0, 2, 3])  # row 1 has no joint terms
BODY = [(0, 20), (5, 20), (10, 15), (15, 20)]  # the columns a row's bodies can fill (zero elsewhere)
P = NB + len(TERM_ROWS) * NT


def _chunk(rng, n):
    Wb = rng.standard_normal((n, ROWS, NB))
    for r, (c0, c1) in enumerate(BODY):
        Wb[:, r, :c0] = 0.0
        Wb[:, r, c1:] = 0.0
    F = rng.standard_normal((n, len(TERM_ROWS), NT))
    y = rng.standard_normal((n, ROWS))
    keep = np.ones((n, ROWS))
    keep[rng.random((n, ROWS)) < 0.1] = 0.0  # left out of the fit (rest, reversals)
    return Wb, F, y, keep


def _row_major(Wb, F):
    n = Wb.shape[0]
    X = np.zeros((ROWS, n, NB + NT))
    X[:, :, :NB] = Wb.transpose(1, 0, 2)
    X[TERM_ROWS, :, NB:] = F.transpose(1, 0, 2)
    return X


def _dense(Wb, F):
    W = np.zeros((Wb.shape[0], ROWS, P))
    W[:, :, :NB] = Wb
    for k, r in enumerate(TERM_ROWS):
        W[:, r, NB + k * NT : NB + (k + 1) * NT] = F[:, k]
    return W


def _close(a, b, tol=1e-12):
    assert np.abs(a - b).max() <= tol * max(np.abs(b).max(), 1.0)


def test_row_major_fold_equals_fold_chunk_per_fold_and_left_out():
    rng = np.random.default_rng(4)
    term_of = {int(r): k for k, r in enumerate(TERM_ROWS)}
    ranges = [(c0, NB + NT) if r in term_of else (c0, c1) for r, (c0, c1) in enumerate(BODY)]
    acc = RowMajorFold(3, ranges, [term_of.get(r) for r in range(ROWS)], NB, NT, P, track_left_out=True)
    ref = [NormalEquations.zeros(ROWS, P, left_out=True) for _ in range(3)]
    dense = NormalEquations.zeros(ROWS, P)
    structure = SimpleNamespace(term_rows=TERM_ROWS)
    start = 0
    for n in (70, 129, 1, 50):  # chunk boundaries anywhere, inside fold runs
        Wb, F, y, keep = _chunk(rng, n)
        folds = ((np.arange(start, start + n) // 37) * 2) % 3  # runs of 37 samples, folds revisited
        start += n
        fold_chunk(ref, folds, structure, Wb.copy(), F.copy(), y.copy(), keep, [BODY[r] for r in range(ROWS)], True)
        dense.add(_dense(Wb, F) * keep[:, :, None], y * keep)
        acc.add(_row_major(Wb, F), y.copy(), keep, folds)
    for ne in ref:
        ne.mirror_upper()
    got = acc.equations()
    assert [g.n_samples for g in got] == [r.n_samples for r in ref] and sum(g.n_samples for g in got) == start
    for g, r in zip(got, ref):
        for a, b in ((g.A, r.A), (g.b, r.b), (g.c, r.c), (g.y_min, r.y_min), (g.y_max, r.y_max), (g.y_sum, r.y_sum),
                     (g.left_out.A, r.left_out.A), (g.left_out.b, r.left_out.b), (g.left_out.c, r.left_out.c)):
            _close(a, b)
        assert g.left_out.n_samples == r.left_out.n_samples > 0
    total = got[0].merge(got[1]).merge(got[2])
    _close(total.A, dense.A)
    _close(total.b, dense.b)
    _close(total.c, dense.c)


def test_row_major_fold_without_masks_or_folds():
    rng = np.random.default_rng(5)
    Wb, F, y, _ = _chunk(rng, 90)
    ranges = [(0, NB + NT)] * ROWS
    term = [0, None, 1, 2]
    acc = RowMajorFold(1, ranges, term, NB, NT, P)
    acc.add(_row_major(Wb, F), y, None, None)
    dense = NormalEquations.zeros(ROWS, P)
    dense.add(_dense(Wb, F), y)
    (got,) = acc.equations()
    assert got.left_out is None and got.n_samples == 90
    _close(got.A, dense.A)
    _close(got.b, dense.b)
    _close(got.c, dense.c)
