"""Which axis of a stored array is time.

A Trajectory is sample-major (``q[i, j]``: sample i, joint j). Array files may store
channels × samples instead: MATLAB users often keep one row per joint, and Fortran-order
writers (MATLAB v7.3, Julia) transpose what they store. The sample count N is the length of
the time vector; without one it is the axis of ``q`` whose length is not the joint count n
(the robot's, or the joint names'); without either, the longer axis of ``q``. Each 2-D
per-sample array whose *second* axis alone has N entries is transposed; an N × N array cannot
be told apart and is an error naming it.
"""

from __future__ import annotations

import numpy as np

from ..errors import ShapeMismatchError
from .names import RawLog

__all__ = ["orient_samples"]


def _ambiguous(label: str, shape: tuple, why: str, src: str) -> ShapeMismatchError:
    return ShapeMismatchError(
        f"array '{label}' is {shape[0]} × {shape[1]} and {why}: cannot tell which axis is time; store it samples × "
        "channels with more samples than channels (or add a time vector of another length)", src)


def _sample_count(raw: RawLog, n_joints: int | None, src: str) -> int | None:
    t = raw.arrays.get("t")
    if t is not None and t.ndim == 1:
        return t.shape[0]
    q = raw.arrays.get("q")
    if q is None or q.ndim != 2:
        return q.shape[0] if q is not None and q.ndim == 1 else None
    rows, cols = q.shape
    label = raw.origin.get("q", "q")
    if n_joints is not None and (rows == n_joints) != (cols == n_joints):
        return cols if rows == n_joints else rows
    if rows == cols:
        why = (f"the model has {n_joints} joints" if n_joints == rows else "there is no time vector")
        raise _ambiguous(label, q.shape, why, src)
    return max(rows, cols)


def orient_samples(raw: RawLog, n_joints: int | None, src: str) -> list[str]:
    """Make every per-sample array of ``raw`` sample-major, in place (module docstring);
    returns the labels of the arrays that were transposed."""
    t = raw.arrays.get("t")
    if t is not None and t.ndim == 2 and 1 in t.shape:
        raw.arrays["t"] = t.reshape(-1)  # a MATLAB row or column vector
    n = _sample_count(raw, n_joints, src)
    if n is None:
        return []
    flipped = []
    for store in (raw.arrays, raw.extras):
        for key, arr in store.items():
            if key == "t" or arr.ndim != 2:
                continue
            rows, cols = arr.shape
            label = raw.origin.get(key, key)
            if rows == n and cols == n and n > 1:
                raise _ambiguous(label, arr.shape, f"the log has {n} samples", src)
            if cols == n and rows != n:
                store[key] = np.ascontiguousarray(arr.T)
                flipped.append(label)
    return flipped
