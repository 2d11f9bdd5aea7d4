"""Identification of one long log in a single streamed pass (what ``sensorless identify`` runs on long logs).

The whole-log path holds the preprocessed log in memory and passes over it three times: the
friction-candidate compression, the five cross-validation folds of γ, and the friction plot. Here:

1. :func:`~sensorless.data.streamed_log.scan_log` measures what needs the whole log (noise, rest,
   outliers, the P95 speed scale, the excitation period), one joint's column at a time;
2. the friction law (ε from σ_v, the Stribeck and transition-width candidates) follows from those
   figures exactly as :func:`~.friction.friction_structure` computes it on the whole log;
3. one pass evaluates the regressor of each preprocessed chunk once, with the candidate columns
   (:class:`~.stribeck.StribeckCandidates`), and folds each sample into the normal equations of
   its cross-validation fold (the phase block of :func:`~.gamma.cross_validate_gamma`: whole
   excitation periods, or contiguous blocks without one). The folds sum to the log's equations
   (normal equations are additive), so the Stribeck choice, the γ cross-validation (the chosen
   columns mapped out of each fold) and the final fit all run on compressed equations:
   :func:`~.identify.identify` with ``folds``. Memory is O(rows · p² · folds), not O(N). With more than
   one CPU, the joint features of chunk k are computed and folded in a helper thread while chunk k + 1
   is read and its regressor evaluated (NumPy, BLAS and the C++ kernels release the GIL).

The torque-channel checks (:class:`~.torque_channels.TorqueChannels`) see the log in blocks of
:data:`CHANNEL_BLOCK` samples (a dead run is measured within a block); the plots get the first
:data:`PLOT_SAMPLES` samples and an evenly strided subsample of as many.

The equations left out of the fit at velocity reversals are found between neighbouring samples of
the log (a one-sample look-ahead across chunks), in the folds too (the whole-log path tests the
neighbours within each fold's concatenated blocks, so a block edge can count as a reversal there:
the γ scores differ by those few samples, the equations of the final fit do not).

:func:`streamed_identify` returns None when the log is not one this path reproduces (see
:func:`~sensorless.data.streamed_log.scan_log` and :func:`~sensorless.data.chunks.open_chunked`).
"""

from __future__ import annotations

import dataclasses
import functools
import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numpy as np

from ..data.chunks import ChunkedLog, open_chunked
from ..data.streamed_log import StreamedLog, scan_log
from ..data.trajectory import Trajectory
from ..errors import DataError
from ..regressor.normal_equations import NormalEquations, RowMajorFold, one_blas_thread
from ..regressor.joint_terms import joint_term, terms_where
from ..regressor.terms import ModelStructure
from .friction import FrictionFit, coulomb_smoothing_from_noise, friction_structure, record_search, stribeck_grid, \
    transition_grid
from .stribeck import StribeckCandidates
from .torque_channels import TorqueChannels
from .uncertainty import JointMotion

__all__ = ["STREAM_MIN_SAMPLES", "PLOT_SAMPLES", "StreamedFit", "fold_stream", "streamed_friction",
           "streamed_identify"]

#: ``sensorless identify`` streams a single training log of at least this many samples
STREAM_MIN_SAMPLES = 50_000
#: samples kept for the plots: the first ones (torques.png) and an evenly strided subsample (friction.png)
PLOT_SAMPLES = 20_000
#: the torque-channel checks (:class:`~.torque_channels.TorqueChannels`: dead runs, the prior's scale on a
#: subsample) see the log in blocks of this many samples
CHANNEL_BLOCK = 1 << 16


@dataclasses.dataclass
class StreamedFit:
    """The result of :func:`streamed_identify`: ``result``, its ``structure``, the friction ``fit`` and
    ``law`` (as ``sensorless identify`` records them), the scanned ``log``, and two bounded
    trajectories for the plots: ``head`` (the first :data:`PLOT_SAMPLES`) and ``subsample``."""

    result: object
    structure: ModelStructure
    fit: "FrictionFit | None"
    law: "FrictionFit | None"
    log: StreamedLog
    head: Trajectory
    subsample: Trajectory
    #: the fit's input: the structure before the friction search, its compressed equations and candidate grids
    equations: "tuple | None" = None

    def ols_baseline(self, weights="auto"):
        """The unconstrained least-squares result on the same compressed equations (no pass over the log;
        the comparison column of ``sensorless identify``)."""
        from .identify import identify

        s, ne, grid, widths = self.equations
        return identify(s, ne, method="ols", weights=weights, stribeck_grid=grid, width_grid=widths,
                        check_torques=False, outliers="keep")


def _pooled(sig: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """√(Σ w σ² / Σ w) over logs (one here), the pooling of :mod:`~.friction`."""
    return np.sqrt(np.sum(weights * sig**2, axis=0) / np.sum(weights, axis=0))


def streamed_friction(structure: ModelStructure, slog: StreamedLog, coulomb_smoothing="auto",
                      stribeck_velocity="auto") -> tuple[ModelStructure, FrictionFit]:
    """:func:`~.friction.friction_structure` of the scanned log (width grid "auto", no low-pass), from
    its figures instead of its samples."""
    joints = list(structure.robot.term_joints)
    col = [list(slog.log.joint_names).index(j) for j in joints]
    has_stribeck = [j for j in joints if "stribeck" in structure.terms_of(j)]
    auto_eps = isinstance(coulomb_smoothing, str)
    auto_vs = isinstance(stribeck_velocity, str) and bool(has_stribeck)
    N = float(slog.n_samples)
    moving = slog.moving[col][None, :].copy()
    moving[:, ~moving.any(axis=0)] = True
    w = N * moving
    speed = slog.speed[col]
    speed = np.where(speed > 0, speed, 1.0)
    sigma_v = None
    if auto_eps:
        sigma_v = _pooled(slog.velocity_noise[col][None, :], w)
        eps = coulomb_smoothing_from_noise(sigma_v, speed=speed, factor=3.0)
    else:
        eps = np.full(len(joints), float(coulomb_smoothing))
    rest = np.zeros(len(joints))
    limits = dict(zip(structure.robot.joint_names, structure.robot.velocity_limits()))
    vlim = np.array([limits.get(j, np.inf) for j in joints])
    law = [j for j in joints if any(joint_term(t).reversal for t in structure.terms_of(j))]
    widths = transition_grid(speed, eps, joints, law, vlim) if auto_eps and structure.friction_law == "blend" else None
    low = np.array([min([eps[k]] + (widths or {}).get(j, [])) for k, j in enumerate(joints)])
    if auto_vs:
        vs = {j: float(0.1 * speed[k]) for k, j in enumerate(joints) if j in has_stribeck}
        grid = stribeck_grid(speed, low, rest, joints, has_stribeck, vlim)
    else:
        vs = ({j: float(stribeck_velocity) for j in has_stribeck} or None) if not isinstance(stribeck_velocity, str) \
            else None
        grid = None
    s = dataclasses.replace(structure, coulomb_smoothing=dict(zip(joints, map(float, eps))), stribeck_velocity=vs,
                            per_joint_terms=None if structure.per_joint_terms is None else dict(structure.per_joint_terms),
                            rest_velocity=None)
    fit = FrictionFit(coulomb_smoothing=dict(zip(joints, map(float, eps))),
                      coulomb_smoothing_mode="auto" if auto_eps else "given", stribeck_velocity=vs, stribeck_grid=grid,
                      rest_velocity=dict(zip(joints, map(float, rest))), rest_velocity_mode="off",
                      width_grid=widths or None)
    if sigma_v is not None:
        fit.velocity_noise = dict(zip(joints, map(float, sigma_v)))
        tau_cols = [list(slog.log.joint_names).index(structure.robot.actuated_joints[k])
                    for k in range(len(structure.actuated_rows))]
        fit.torque_noise = dict(zip(joints, map(float, _pooled(slog.torque_noise[tau_cols][None, :],
                                                                np.array([[N]])))))
    return s, fit


def _fold_index(slog: StreamedLog, n_folds: int) -> Callable[[int, int], np.ndarray]:
    """fold of samples [s, e): the phase block of :func:`~.gamma.cross_validate_gamma` (period found on
    the log) or the contiguous block (none found)."""
    t0, P, N = slog.t[0], slog.period, slog.n_samples
    if P is not None:
        return lambda s, e: np.floor(((slog.t[s:e] - t0) % P) / P * n_folds).astype(int)
    edges = np.linspace(0, N, n_folds + 1).round().astype(int)
    return lambda s, e: np.searchsorted(edges, np.arange(s, e), side="right") - 1


def fold_stream(structure, slog: StreamedLog, *, n_folds: int = 1, chunk: int = 2048,
                progress: Callable[[int], None] | None = None, on_chunk: Callable[[int, int, Trajectory], None] | None = None,
                overlap: "bool | None" = None) -> list[NormalEquations]:
    """Normal equations of the preprocessed log, one set per cross-validation fold (``n_folds`` ≥ 2) or
    one set; ``structure`` as :func:`~sensorless.regressor.compress` reads it (a model or the friction
    candidates). Each chunk's regressor is evaluated once. ``on_chunk(start, n, chunk)`` sees each chunk.
    ``overlap``: compute the joint features (the candidate columns) of chunk k and fold it in a helper
    thread while chunk k + 1 is read and its regressor evaluated (default: with more than one CPU, even a
    busy one: the two halves are balanced and hand over a chunk at a time, with no spinning BLAS threads,
    so on the 2-CPU benchmark machine the pass took 0.65× the time when idle and 0.75–0.85× with one or two
    busy processes beside it); the sums do not depend on it."""
    track = bool(getattr(structure, "track_left_out", False))
    if structure.row_map.per_sample or set(terms_where("stateful")) & set(getattr(structure, "joint_terms", ())):
        raise DataError("the streamed pass folds per-joint rows of a fixed map (no contacts, no presliding)")
    fold_of = _fold_index(slog, n_folds) if n_folds > 1 else None
    rows, nb, term_rows = structure.n_rows, structure.n_block_params, np.asarray(structure.term_rows)
    nt = (structure.n_params - nb) // len(term_rows) if len(term_rows) else 0
    dense = not structure.row_map.selects_rows or structure.n_block_params != structure.n_body_params
    body = [(0, nb)] * rows if dense else structure.row_body_columns()
    term_of = {int(r): k for k, r in enumerate(term_rows)}
    ranges = [(c0, nb + nt) if r in term_of and nt else (c0, c1) for r, (c0, c1) in enumerate(body)]
    acc = RowMajorFold(n_folds, ranges, [term_of.get(r) for r in range(rows)], nb, nt, structure.n_params, track)
    if overlap is None:
        overlap = (os.cpu_count() or 1) > 1
    # row-major chunks: the regressor and the joint features are written in place (views), rows of X[r] are samples
    bufs = [np.zeros((rows, chunk, nb + nt)) for _ in range(2 if overlap else 1)]
    in_place = np.array_equal(term_rows, np.arange(rows)) and isinstance(structure, StribeckCandidates)
    pending: list = [None] * len(bufs)
    prev_v = None

    def fold(X, n, part, V, A, prev_v, folds):  # targets, masks, joint features (candidate columns), the fold
        y = structure.target(part)[:n]
        keep = structure.fit_mask(V if prev_v is None else np.concatenate([prev_v, V]))
        if keep is not None:  # seen with the neighbour samples (a reversal), as on the whole log
            keep = keep[(0 if prev_v is None else 1):][:n]
        terms = X[:, :n, nb:].transpose(1, 0, 2)
        if in_place:
            structure.joint_features(V[:n], A[:n], None, out=terms)
        elif nt:
            terms[:, term_rows] = structure.joint_features(V[:n], A[:n], None)
        acc.add(X[:, :n], y, keep, folds)

    with one_blas_thread(), ThreadPoolExecutor(1) as pool:
        for k, (s, n, part) in enumerate(slog.chunks(chunk)):
            if on_chunk is not None:
                on_chunk(s, n, part)
            slot = k % len(bufs)
            if pending[slot] is not None:  # the fold still reading this buffer
                pending[slot].result()
            X = bufs[slot]
            Q, V, A = structure.state(part)
            structure.block_regressor(Q[:n], V[:n], A[:n], out=X[:, :n, :nb].transpose(1, 0, 2))
            folds = fold_of(s, s + n) if fold_of is not None else None
            job = (X, n, part, V, A, prev_v, folds)
            prev_v = V[n - 1 : n]
            if overlap:
                pending[slot] = pool.submit(fold, *job)
            else:
                fold(*job)
            if progress is not None:
                progress(n)
        for f in pending:
            if f is not None:
                f.result()
    return acc.equations()


def _plot_samples(slog: StreamedLog, n: int):
    """(on_chunk, result): the first ``n`` preprocessed samples and every k-th (≤ ``n``) of the log."""
    stride = max(1, -(-slog.n_samples // n))
    head, sub = [], []

    def on_chunk(s: int, m: int, part: Trajectory) -> None:
        if s < n:
            head.append(part.take(slice(0, min(m, n - s))))
        first = (-s) % stride
        if first < m:
            sub.append(part.take(np.arange(first, m, stride)))

    return on_chunk, lambda: (_concat(head, slog), _concat(sub, slog))


def _concat(parts: list, slog: StreamedLog) -> Trajectory:
    cat = lambda k: np.concatenate([getattr(p, k) for p in parts])  # noqa: E731
    return Trajectory(t=cat("t"), q=cat("q"), v=cat("v"), a=cat("a"), tau=cat("tau"),
                      joint_names=list(slog.log.joint_names), source=slog.source, provenance=dict(slog.provenance))


def streamed_identify(structure: ModelStructure, path, *, method: str = "lmi", friction: bool = True,
                      coulomb_smoothing="auto", stribeck_velocity="auto", rest: str = "auto",
                      min_samples: int = STREAM_MIN_SAMPLES, check_torques: bool = True, chunk: int = 2048,
                      progress: Callable[[int], None] | None = None, **identify_kwargs) -> "StreamedFit | None":
    """Identify ``structure`` from the log at ``path`` in one streamed pass (module docstring), or None
    when this path does not apply (format, layout, length, timing or outliers: the whole-log path
    then reads it). ``friction``: measure the friction law as ``sensorless identify`` does (ε and the
    candidate grids); ``identify_kwargs`` as :func:`~.identify.identify`."""
    from .identify import identify

    log = path if isinstance(path, ChunkedLog) else open_chunked(path, structure.robot.joint_names)
    if log is None:
        return None
    cv = method == "lmi" and identify_kwargs.get("gamma") == "auto"
    slog = scan_log(log, rest=rest, min_samples=min_samples, period=cv)
    if slog is None:
        return None
    law = fit = None
    s, grid, widths = structure, None, None
    if friction:
        _, law = streamed_friction(structure, slog, coulomb_smoothing, stribeck_velocity)
        given = dict(coulomb_smoothing=law.coulomb_smoothing if coulomb_smoothing == "auto" else coulomb_smoothing,
                     stribeck_velocity=law.stribeck_grid or stribeck_velocity, width_grid=law.width_grid)
        s, fit = friction_structure(structure, [], **given)
        grid = law.stribeck_grid if isinstance(given["stribeck_velocity"], dict) else None
        widths = law.width_grid
    cand = StribeckCandidates(s, grid, widths) if (grid or widths) else s
    on_chunk, plots = _plot_samples(slog, PLOT_SAMPLES)
    motion = JointMotion(s.robot.joint_names)
    channels = TorqueChannels(s) if check_torques else None

    block: list = []

    def check(final: bool = False) -> None:  # the torque channels see blocks of CHANNEL_BLOCK samples
        if block and (final or sum(map(len, block)) >= CHANNEL_BLOCK):
            channels.add(_concat(block, slog))
            block.clear()

    def watch(start: int, n: int, part: Trajectory) -> None:
        on_chunk(start, n, part)
        body = part.take(slice(0, n))
        motion.add(body)
        if channels is not None:
            block.append(body)
            check()

    from .gamma import CV_FOLDS  # here: gamma imports cvxpy, which --method ols never needs

    folds = fold_stream(cand, slog, n_folds=CV_FOLDS if cv else 1, chunk=chunk, progress=progress, on_chunk=watch)
    if channels is not None:
        check(final=True)
    empty = [f for f, ne in enumerate(folds) if ne.n_samples == 0]
    if cv and empty:
        raise DataError(f"no sample falls in phase block {empty[0]} of {CV_FOLDS}; is the period of {slog.period} s right?",
                        slog.source)
    total = functools.reduce(NormalEquations.merge, folds)
    result = identify(s, total, method=method, chunk=chunk, stribeck_grid=grid, width_grid=widths,
                      folds=folds if cv else None, motion=motion, channels=channels,
                      check_torques=check_torques, **identify_kwargs)
    if fit is not None and (grid or widths):
        fit = record_search(fit, result)
    result.settings["streamed"] = {"chunk": chunk, "n_samples": slog.n_samples, "folds": CV_FOLDS if cv else 1,
                                   "fold_period_s": slog.period if cv else None}
    head, sub = plots()
    return StreamedFit(result, result.structure, fit, law, slog, head, sub, (s, total, grid, widths))


#: preprocessing options (``sensorless identify``'s) under which the streamed pass gives the whole-log samples
_DEFAULTS = {"columns": None, "rate": None, "lowpass": None, "savgol_window": None, "decimate": 1, "gains": None,
             "resample": "auto", "velocity": "logged", "time_unit": None, "wrench_frames": None}


def _value(x):
    x = getattr(x, "value", x)  # an option's enum
    return None if x is None or (isinstance(x, (str, dict, list)) and not x) else x


def streamable(stream: "bool | None", data: list, robot, prep: dict, *, scheduler=None, skip_bad=False,
               imu_frame=None, contact_frames=None, passive=None, joint_terms: str = "") -> "ChunkedLog | None":
    """The chunked reader of ``sensorless identify``'s single training log when the streamed pass
    applies (``stream``: None = auto, False = never), else None. It does not apply with several logs,
    ``--scheduler``, ``--skip-bad``, a trim, preprocessing options other than the defaults (low-pass,
    Savitzky–Golay window, decimation, resampling rate, column map, gains, time unit), a floating base,
    contacts, passive joints, an IMU frame or presliding, nor to a file format or layout
    :func:`~sensorless.data.chunks.open_chunked` does not know: those logs are read whole."""
    from ..data.limits import current_options

    if stream is False or scheduler is not None or skip_bad or imu_frame or contact_frames or passive:
        return None
    if len(data) != 1 or getattr(robot, "floating_base", False) or any(t in (joint_terms or "") for t in terms_where("stateful")):
        return None
    trim = prep.get("trim")
    if trim is not None and (not hasattr(trim, "window_for") or trim.window_for(data[0]) is not None):
        return None
    if any(_value(prep.get(k)) != _value(v) for k, v in _DEFAULTS.items()):
        return None
    opts = current_options()
    if opts.get("skip_bad_rows") or opts.get("angle_unit") not in (None, "rad"):
        return None
    return open_chunked(data[0], robot.joint_names)


def identify_streamed(log: ChunkedLog, structure, method: str, friction: bool, coulomb_smoothing, stribeck_velocity,
                      rest, kw: dict, min_samples: "int | None" = None) -> "StreamedFit | None":
    """:func:`streamed_identify` with ``sensorless identify``'s keyword arguments ``kw`` (the PhysicalModel
    ones); None when the log is shorter than ``min_samples`` (default :data:`STREAM_MIN_SAMPLES`) or the
    scan finds it needs the whole-log path."""
    from ..errors import ExcitationError

    kw = dict(kw)
    progress, check = kw.pop("progress", None), kw.pop("check_torques", True)
    try:
        return streamed_identify(structure, log, method=method, friction=friction,
                                 coulomb_smoothing=coulomb_smoothing, stribeck_velocity=stribeck_velocity,
                                 rest=str(getattr(rest, "value", rest)),
                                 min_samples=STREAM_MIN_SAMPLES if min_samples is None else min_samples,
                                 check_torques=check, progress=progress, **kw)
    except ExcitationError as exc:  # named by its file, as the whole-log path does
        raise ExcitationError(f"{log.path}: {exc}") from None
