"""Fleet-scale compression on Dask: files → partial normal equations → tree sum.

The compressed normal equations (:mod:`.normal_equations`) are sums over samples, hence over files,

    A_r = Σ_files Σ_i W_{i,r}ᵀ W_{i,r},   b_r = Σ_files Σ_i W_{i,r}ᵀ y_{i,r},   c_r = …

so identification over many logs is a map-reduce. Each Dask task reads one file on its
worker, preprocesses it exactly like the local path (:class:`LogReader`, i.e.
``cli.common.load_log``: read → low-pass → Savitzky–Golay → decimate) and folds it with
:func:`~.normal_equations.compress_trajectories`. The partial sums are added by a fixed tree of merge tasks
(``split_every`` inputs per node, so the summation order does not depend on which task
finishes first) and the client receives one :class:`~.normal_equations.NormalEquations` of size
O(rows · p²). Only the pickled model structure (scattered once to every worker, unpickled
once per worker thread because a Pinocchio ``Data`` is per-thread scratch space) and the
reader settings travel; the arrays never leave the worker that read them.

Dask does the scheduling: tasks of a worker that dies are rerun elsewhere, a task that
raises is retried ``retries`` times. A file that cannot be used is not such a failure: its task
returns the typed error (naming the file) as a value, which the client raises, the same one-line
error as a single-process run, with no retry and nothing in the workers' logs; with ``skip_bad``
the file is skipped and listed in :attr:`FleetEquations.skipped`. The client comes from
:func:`sensorless.regressor.dask_cluster.connect`.

Two-step WLS needs no second pass over the files: the per-row equations give every row's
OLS residual ‖W_r π − y_r‖² = πᵀA_rπ − 2πᵀb_r + c_r exactly. LMI with γ chosen by
cross-validation needs the samples split into folds exactly as
``identification.gamma.split_folds`` does: pass 1 returns each file's length and excitation
period, pass 2 folds each file's samples into ``n_folds`` partial equations.
"""

from __future__ import annotations

import functools
import glob
import hashlib
import os
import pickle
import threading
import time
import uuid
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import DataError, DistributedError, SensorlessError
from .normal_equations import NormalEquations, compress_folds, compress_trajectories
from .terms import ModelStructure

if TYPE_CHECKING:
    from ..data.trims import LogTrims

__all__ = ["FleetEquations", "LogReader", "PickledModel", "compress_files", "expand_paths", "worker_structure"]

_GLOB_CHARS = frozenset("*?[")


# ---- what travels to the workers -----------------------------------------------------------


@dataclass(frozen=True)
class LogReader:
    """Preprocessing settings of a log; calling it reads and preprocesses one file.

    The same function (``cli.common.load_log``) as the local path, so a worker sees exactly
    the samples a single-process run would.
    """

    columns: str | None = None
    rate: float | None = None
    lowpass: float | None = None
    savgol_window: int | None = None
    decimate: int = 1
    gains: Any = None
    trim: "str | LogTrims | None" = None  # a window for every log, or each log's own (data.trims.LogTrims)
    resample: str = "auto"
    velocity: str = "logged"
    max_gap: float | None = None
    outliers: str = "error"
    rest: str = "auto"
    time_unit: str | None = None
    base_velocity: str | None = None
    pose_max_gap: float | None = None
    wrench_frames: dict | None = None  # {contact frame: frame its wrench is logged in} (data.wrench_frames)
    imu_frame: str | None = None  # base_a from the accelerometer in this model frame (data.prepare.with_imu_frame)
    skip_bad_rows: bool | None = None  # drop a corrupt prefix/suffix of rows (data.bad_rows)
    angle_unit: str | None = None  # "deg": joint angles logged in degrees (data.angles)

    def __call__(self, path: str | Path, robot) -> Trajectory:
        from ..data.prepare import load_log, with_imu_frame

        traj = load_log(path, robot, self.columns, self.rate, self.lowpass, self.savgol_window, self.decimate,
                        gains=self.gains, trim=self.trim, resample=self.resample, velocity=self.velocity,
                        max_gap=self.max_gap, outliers=self.outliers, rest=self.rest, time_unit=self.time_unit,
                        base_velocity=self.base_velocity, pose_max_gap=self.pose_max_gap,
                        wrench_frames=self.wrench_frames,
                        skip_bad_rows=self.skip_bad_rows, angle_unit=self.angle_unit)
        return with_imu_frame(traj, robot, self.imu_frame, self.savgol_window) if self.imu_frame else traj

    def settings(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class PickledModel:
    """A model structure as pickled bytes plus their digest (the per-worker cache key)."""

    token: str
    blob: bytes

    @classmethod
    def of(cls, structure: ModelStructure) -> "PickledModel":
        try:
            blob = pickle.dumps(structure, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # noqa: BLE001 - e.g. a robot built from an unpicklable object
            raise DistributedError(
                f"the model structure cannot be sent to the workers ({type(exc).__name__}: {exc})"
            ) from None
        return cls(hashlib.sha256(blob).hexdigest(), blob)


_CACHE: dict[tuple[str, int], ModelStructure] = {}
_CACHE_LOCK = threading.Lock()


def worker_structure(model: ModelStructure | PickledModel) -> ModelStructure:
    """The structure for this thread: unpickled once per (model, worker thread), then cached."""
    if isinstance(model, ModelStructure):
        return model
    key = (model.token, threading.get_ident())
    s = _CACHE.get(key)
    if s is None:
        s = pickle.loads(model.blob)
        with _CACHE_LOCK:
            if len(_CACHE) >= 32:
                _CACHE.clear()
            _CACHE[key] = s
    return s


# ---- partial results and their sum ----------------------------------------------------------


@dataclass
class _Part:
    """What a task returns: partial equations (and per-fold ones), files used, files skipped."""

    ne: NormalEquations | None
    folds: list[NormalEquations | None] | None
    files: list[str]
    skipped: list[tuple[str, str]]


@dataclass
class _Failed:
    """What a task returns for a file that cannot be used (without ``skip_bad``): its typed error."""

    error: SensorlessError


def _failure(part) -> SensorlessError | None:
    """The error a task returned (a probe run next to the task's result: only the error travels)."""
    return part.error if isinstance(part, _Failed) else None


def _add(a: NormalEquations | None, b: NormalEquations | None) -> NormalEquations | None:
    return b if a is None else a if b is None else a.merge(b)


def _merge(*parts: "_Part | _Failed") -> "_Part | _Failed":
    """Sum of partial results, in argument order (a node of the reduction tree); the first failure wins."""
    failed = next((p for p in parts if isinstance(p, _Failed)), None)
    if failed is not None:
        return failed
    out = _Part(None, None, [], [])
    for p in parts:
        out.ne = _add(out.ne, p.ne)
        if p.folds is not None:
            out.folds = list(p.folds) if out.folds is None else [_add(x, y) for x, y in zip(out.folds, p.folds)]
        out.files = out.files + p.files
        out.skipped = out.skipped + p.skipped
    return out


def _named(exc: SensorlessError, path: str) -> SensorlessError:
    """The error, with the file name in front if its message does not name it already."""
    msg = str(exc)
    if path in msg:
        return exc
    try:
        return type(exc)(f"{path}: {msg}")
    except Exception:  # noqa: BLE001 - an error class with another signature
        return DataError(msg, path)


def _fold_ids(traj: Trajectory, n_folds: int, period: float | None, offset: int, total: int) -> np.ndarray:
    """The cross-validation fold of each sample of this file, as ``gamma.split_folds`` cuts them:
    phase blocks ``⌊((t − t₀) mod period) / period · n_folds⌋`` per file when a period is
    known, else contiguous blocks of the concatenated samples (``offset`` = samples before this file)."""
    if period is not None:
        return np.floor(((traj.t - traj.t[0]) % period) / period * n_folds).astype(int)
    edges = np.linspace(0, total, n_folds + 1).round().astype(int)
    return np.searchsorted(edges, offset + np.arange(len(traj)), side="right") - 1


def _file_folds(structure, traj: Trajectory, plan: tuple, chunk: int) -> list:
    """This file's share of each fold (None where it has no sample): one pass with the whole
    file's fit masks (:func:`~.normal_equations.compress_folds`), or, for structures that fold
    their own equations (contacts), each fold's samples compressed apart."""
    ids = _fold_ids(traj, *plan)
    n_folds = plan[0]
    if structure.row_map.per_sample:
        return [compress_trajectories(structure, traj.take(ids == f), chunk=chunk) if np.any(ids == f) else None
                for f in range(n_folds)]
    folds = compress_folds(structure, traj, lambda k, t: lambda lo, hi: ids[lo:hi], n_folds, chunk=chunk)
    return [ne if np.any(ids == f) else None for f, ne in enumerate(folds)]


def _file_task(model, reader, path: str, chunk: int, skip_bad: bool, plan: tuple | None) -> "_Part | _Failed":
    """Map step: read + preprocess one file on this worker and fold it into normal equations.

    ``plan = (n_folds, period, offset, total)`` also splits it into cross-validation folds
    (the file's total is then the sum of its folds).
    """
    structure = worker_structure(model)
    try:
        traj = reader(path, structure.robot)
        if plan is None:
            return _Part(compress_trajectories(structure, traj, chunk=chunk), None, [path], [])
        folds = _file_folds(structure, traj, plan, chunk)
        return _Part(functools.reduce(_add, folds), folds, [path], [])
    except SensorlessError as exc:
        if not skip_bad:
            return _Failed(_named(exc, path))
        return _Part(None, None if plan is None else [None] * plan[0], [], [(path, str(_named(exc, path)))])


def _length_task(model, reader, path: str, skip_bad: bool) -> "tuple[int | None, float | None, str | None] | _Failed":
    """Pass 1 of cross-validation folds: (samples after preprocessing, excitation period, error)."""
    from ..data.periodicity import excitation_period

    structure = worker_structure(model)
    try:
        traj = reader(path, structure.robot)
    except SensorlessError as exc:
        if not skip_bad:
            return _Failed(_named(exc, path))
        return None, None, str(_named(exc, path))
    return len(traj), excitation_period(traj), None


# ---- result ----------------------------------------------------------------------------------


@dataclass
class FleetEquations:
    """Normal equations summed over files, with the files used and those skipped (and why)."""

    equations: NormalEquations
    files: list[str]
    skipped: list[tuple[str, str]] = field(default_factory=list)
    folds: list[NormalEquations] | None = None
    period: float | None = None
    seconds: float = 0.0

    def summary(self) -> dict:
        return {
            "files_used": len(self.files),
            "skipped_files": [{"file": f, "error": e} for f, e in self.skipped],
            "n_samples": self.equations.n_samples,
        }


# ---- driver ----------------------------------------------------------------------------------


def expand_paths(patterns: Sequence[str | Path] | str | Path) -> list[str]:
    """File paths from paths and glob patterns (``**`` is recursive), in the order given and
    sorted within a pattern. A pattern that matches no file raises :class:`DataError` naming it;
    plain paths are kept as they are (reading reports a missing one)."""
    if isinstance(patterns, (str, Path)):
        patterns = [patterns]
    out: list[str] = []
    for p in patterns:
        s = os.path.expanduser(str(p))
        if _GLOB_CHARS & set(s):
            hits = sorted(h for h in glob.glob(s, recursive=True) if os.path.isfile(h))
            if not hits:
                raise DataError("the pattern matches no file", s)
            out += hits
        else:
            out.append(s)
    return out


def _paths(data) -> list[str]:
    items = [data] if isinstance(data, (str, Path, Trajectory)) else list(data)
    bad = [i for i in items if not isinstance(i, (str, Path))]
    if bad:
        src = getattr(bad[0], "source", None) or type(bad[0]).__name__
        raise DataError("with a Dask client, pass file paths: workers read their own files and "
                        "arrays are never shipped", src)
    files = expand_paths(items)
    if not files:
        raise DataError("no file was given")
    return files


def compress_files(
    structure: ModelStructure,
    files: Sequence[str | Path] | str | Path,
    *,
    client=None,
    reader: Callable[[str, Any], Trajectory] | None = None,
    chunk: int = 2048,
    skip_bad: bool = False,
    retries: int = 2,
    split_every: int = 8,
    n_folds: int | None = None,
    period: float | str | None = "auto",
    progress: Callable[[int], None] | None = None,
) -> FleetEquations:
    """Compress logs given as file paths (or glob patterns), one task per file.

    ``client``: a ``distributed.Client`` (None: the same tasks run one after another in this
    process). ``reader(path, robot) -> Trajectory`` reads and preprocesses one file (default
    :class:`LogReader`\\ (): the CLI defaults); it must be picklable. A file that fails raises
    its typed error naming it, unless ``skip_bad`` (then it is listed in ``skipped``).
    ``retries``: Dask retries of a task that raised. ``n_folds`` also returns the
    cross-validation folds of ``gamma.cross_validate_gamma`` (``period`` as there; this costs
    a first pass that reads every file for its length). ``progress(1)`` is called per finished
    file task (twice per file with folds).
    """
    reader = LogReader() if reader is None else reader
    paths = _paths(files)
    t0 = time.perf_counter()
    runner = _Local(structure, progress)
    if client is not None:
        runner = _Dask(client, PickledModel.of(structure), retries, split_every, progress)
    folds_plan: list[tuple | None] = [None] * len(paths)
    found_period, skipped_first = None, []
    if n_folds is not None:
        lengths = runner.lengths(reader, paths, skip_bad)
        good = [(p, n, per) for p, (n, per, err) in zip(paths, lengths) if err is None]
        if not good:
            raise DataError("every file was skipped: " + "; ".join(err for _, _, err in lengths if err))
        total = sum(n for _, n, _ in good)
        if n_folds < 2 or total < 2 * n_folds:
            raise DataError(f"cannot split {total} samples into {n_folds} folds (need n_folds >= 2)")
        found_period = good[0][2] if period == "auto" else period
        if found_period is not None and not float(found_period) > 0:
            raise DataError(f"period must be positive, got {found_period}")
        skipped_first = [(p, err) for p, (_, _, err) in zip(paths, lengths) if err is not None]
        paths = [p for p, _, _ in good]  # pass 2 reads the files pass 1 could read, at these offsets
        offsets = np.cumsum([0] + [n for _, n, _ in good])[:-1].tolist()
        folds_plan = [(n_folds, found_period, off, total) for off in offsets]
    part = runner.run(reader, paths, chunk, skip_bad, folds_plan)
    part.skipped = skipped_first + part.skipped
    if part.ne is None:
        raise DataError("every file was skipped: " + "; ".join(e for _, e in part.skipped))
    folds = None
    if n_folds is not None:
        empty = [f for f, ne in enumerate(part.folds or []) if ne is None]
        if empty:
            raise DataError(f"no sample falls in phase block {empty[0]} of {n_folds}; is the period of {found_period} s right?")
        folds = part.folds
    return FleetEquations(part.ne, part.files, part.skipped, folds, found_period, time.perf_counter() - t0)


class _Local:
    """The map-reduce run in this process, file after file (same tasks, no Dask)."""

    def __init__(self, model: ModelStructure, progress):
        self.model, self.progress = model, progress

    def _tick(self):
        if self.progress is not None:
            self.progress(1)

    def lengths(self, reader, paths, skip_bad):
        out = []
        for p in paths:
            out.append(_raise_failed(_length_task(self.model, reader, p, skip_bad)))
            self._tick()
        return out

    def run(self, reader, paths, chunk, skip_bad, plans) -> _Part:
        acc = _Part(None, None, [], [])
        for p, plan in zip(paths, plans):
            acc = _merge(acc, _raise_failed(_file_task(self.model, reader, p, chunk, skip_bad, plan)))
            self._tick()
        return acc


def _raise_failed(part):
    if isinstance(part, _Failed):
        raise part.error
    return part


class _Dask:
    """The map-reduce on a Dask cluster: one task per file, a fixed merge tree, gathered on the client."""

    def __init__(self, client, model: PickledModel, retries: int, split_every: int, progress):
        self.client, self.retries, self.progress = client, retries, progress
        self.split_every = max(int(split_every), 2)
        self.tag = uuid.uuid4().hex[:8]
        self.model = client.scatter(model, broadcast=True, hash=False)  # once per worker, not per task

    def lengths(self, reader, paths, skip_bad):
        futs = [self.client.submit(_length_task, self.model, reader, p, skip_bad, key=f"sensorless-length-{self.tag}-{i}",
                                   retries=self.retries, pure=False) for i, p in enumerate(paths)]
        self._wait(futs, paths)
        return [_raise_failed(x) for x in self.client.gather(futs)]

    def run(self, reader, paths, chunk, skip_bad, plans) -> _Part:
        futs = [self.client.submit(_file_task, self.model, reader, p, chunk, skip_bad, plan,
                                   key=f"sensorless-file-{self.tag}-{i}", retries=self.retries, pure=False)
                for i, (p, plan) in enumerate(zip(paths, plans))]
        level, nodes = 0, futs
        while len(nodes) > 1:  # fixed tree: the summation order does not depend on completion order
            k = self.split_every
            nodes = [self.client.submit(_merge, *nodes[i : i + k], key=f"sensorless-merge-{self.tag}-{level}-{i // k}",
                                        retries=self.retries, pure=False) for i in range(0, len(nodes), k)]
            level += 1
        self._wait(futs, paths, extra=nodes)
        try:
            return _raise_failed(nodes[0].result())
        except SensorlessError:
            raise
        except Exception as exc:  # noqa: BLE001
            raise DistributedError(f"the reduction of the partial equations failed ({type(exc).__name__}: {exc})") from exc

    def _wait(self, futs, paths, extra=()):
        """Follow the file tasks as they finish (through probes that fetch only a returned error);
        stop everything at the first failure."""
        from distributed import as_completed

        probes = [self.client.submit(_failure, f, key=f"{f.key}-probe", pure=False) for f in futs]
        index = {pr.key: p for pr, p in zip(probes, paths)}
        try:
            for fut in as_completed(probes):
                if fut.status == "error":
                    exc = fut.exception()
                    if isinstance(exc, SensorlessError):
                        raise exc
                    raise DistributedError(f"{index[fut.key]}: task failed after {self.retries} retries "
                                           f"({type(exc).__name__}: {exc})")
                if fut.status == "cancelled":
                    raise DistributedError(f"{index[fut.key]}: the task was cancelled (scheduler or client lost?)")
                error = fut.result()
                if error is not None:
                    raise error
                if self.progress is not None:
                    self.progress(1)
        except BaseException:
            self.client.cancel(list(futs) + list(extra) + probes)
            raise
