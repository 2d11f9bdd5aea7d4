"""BLAS on one thread while a command runs (unless the user chose a thread count)."""

from __future__ import annotations

import contextlib
import os
from typing import Iterator

__all__ = ["BLAS_ENV", "blas_threads_for_command"]

BLAS_ENV = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")


@contextlib.contextmanager
def blas_threads_for_command() -> Iterator[None]:
    """BLAS on one thread while a command runs, unless the user set ``OPENBLAS_NUM_THREADS`` (or MKL/BLIS).

    The commands' products and factorisations are small (p ≲ a few hundred); threaded BLAS only
    adds synchronisation, and under CPU contention it was measured 39× slower (a 252×84 QR took
    0.3 s). NumPy and SciPy each bundle their own OpenBLAS: the loaded ones are limited with
    threadpoolctl, the ones loaded during the command read the environment variable set here.
    """
    if any(v in os.environ for v in BLAS_ENV):
        yield
        return
    from threadpoolctl import threadpool_limits

    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
    finally:
        os.environ.pop("OPENBLAS_NUM_THREADS", None)
