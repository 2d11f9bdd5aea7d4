"""blocked_folds: contiguous, nearly equal time blocks across logs in order."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.data.blocks import blocked_folds


def test_blocks_are_contiguous_equal_and_span_the_logs_in_order():
    labels = blocked_folds([7, 3, 10], 4)
    flat = np.concatenate(labels)
    assert [len(x) for x in labels] == [7, 3, 10]
    assert np.all(np.diff(flat) >= 0) and set(flat) == {0, 1, 2, 3}  # contiguous, in order
    assert sorted(np.bincount(flat)) == [5, 5, 5, 5]


def test_too_few_samples_is_an_error():
    with pytest.raises(ValueError, match="cannot cut 3 samples into 4"):
        blocked_folds([3], 4)
