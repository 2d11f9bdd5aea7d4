"""The WPI dVRK PSM held-out check: identify on ``one_results``, predict ``two_results``.

Protocol (the authors' split): both logs are read with :func:`~sensorless.robots.dvrk_psm.read_psm_log`
(zero-phase Butterworth at ``cutoff_hz`` = 5.4 Hz on q, q̇ and effort, q̈ by central
differences of the filtered q̇, every sample kept). Errors are per coordinate,
NRMSE = RMSE / (max − min of the measured effort) on ``two_results`` (filtered effort; the
raw effort is reported too).

Hyper-parameters are chosen on the *training* log only: the Coulomb smoothing velocity ε
(sgn → tanh(ṡ/ε)) by contiguous k-fold cross-validation on ``one_results`` (mean NRMSE
over coordinates). The authors' published parameters (``params.json``) are mapped onto the
same structure with :func:`~sensorless.robots.dvrk_psm.published_parameters` and evaluated on the same data.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sensorless.data import Trajectory
from sensorless.errors import DataError
from sensorless.identification import identify, torque_metrics
from sensorless.io import versions
from sensorless.robots.dvrk_psm import psm_structure, published_parameters, read_psm_log

__all__ = [
    "DEFAULT_SMOOTHING",
    "SESSION_OFFSET",
    "ar1_noise",
    "paired_payload_logs",
    "psm_identification_study",
    "psm_split_paths",
    "select_smoothing",
    "write_psm_csv",
]

DEFAULT_SMOOTHING = (0.0, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)


def psm_split_paths(data_dir: str | Path) -> dict[str, Path]:
    """Paths of the WPI files under ``data_dir`` (the folder holding ``data/psm/...``)."""
    root = Path(data_dir)
    paths = {
        "train": root / "data/psm/measured_trajectory/one_results.csv",
        "test": root / "data/psm/measured_trajectory/two_results.csv",
        "params": root / "data/psm/dynamic_params/params.json",
    }
    missing = [str(p) for p in paths.values() if not p.exists()]
    if missing:
        raise DataError(f"missing WPI PSM file(s): {missing}", str(root))
    return paths


def _folds(traj: Trajectory, k: int) -> list[tuple[Trajectory, Trajectory]]:
    edges = np.linspace(0, len(traj), k + 1).astype(int)
    out = []
    for i in range(k):
        val = traj.take(slice(edges[i], edges[i + 1]))
        train = Trajectory.concatenate([traj.take(slice(edges[j], edges[j + 1])) for j in range(k) if j != i])
        out.append((train, val))
    return out


def select_smoothing(
    train: Trajectory,
    candidates: Sequence[float] = DEFAULT_SMOOTHING,
    *,
    folds: int = 3,
    method: str = "ols",
    bodies: str = "authors",
    drives: str = "authors",
) -> tuple[float, dict[float, float]]:
    """ε with the lowest mean validation NRMSE over contiguous folds of ``train``."""
    scores: dict[float, float] = {}
    parts = _folds(train, folds)
    for eps in candidates:
        s = psm_structure(bodies=bodies, drives=drives, coulomb_smoothing=eps)
        vals = []
        for tr, va in parts:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # a fold's identifiability is not the model's (the final fit warns)
                res = identify(s, tr, method=method)
            vals.append(np.mean(res.score(va).nrmse))
        scores[float(eps)] = float(np.mean(vals))
    best = min(scores, key=scores.get)
    return best, scores


def _table(names, metrics) -> dict:
    return {n: float(v) for n, v in zip(names, metrics)}


def psm_identification_study(
    data_dir: str | Path | None = None,
    *,
    train: str | Path | None = None,
    test: str | Path | None = None,
    params: str | Path | None = None,
    results: dict | None = None,
    cutoff_hz: float = 5.4,
    methods: Sequence[str] = ("ols", "wls"),
    smoothing: float | str = "cv",
    candidates: Sequence[float] = DEFAULT_SMOOTHING,
    bodies: str = "authors",
    drives: str = "authors",
    lmi: dict | None = None,
) -> dict:
    """Identify on one_results, evaluate on two_results; JSON-able report (module docstring).

    Files: ``data_dir`` (the WPI folder holding ``data/psm/...``), or ``train`` / ``test``
    logs in the same format (any names) and optionally the authors' ``params`` JSON (the
    published comparison is skipped without it). ``results`` (a dict, optional) receives
    the :class:`~sensorless.identification.IdentificationResult` of each method.
    ``lmi`` (optional) also runs ``identify(method="lmi", **lmi)`` (physically consistent);
    the PSM tree is massless, so it runs unregularised unless ``lmi`` gives a ``prior``.
    """
    t0 = time.perf_counter()
    if train is not None or test is not None:
        if train is None or test is None:
            raise DataError("give both train and test logs (or data_dir)")
        paths = {"train": Path(train), "test": Path(test)}
        if params is not None:
            paths["params"] = Path(params)
        missing = [str(p) for p in paths.values() if not p.exists()]
        if missing:
            raise DataError(f"missing PSM file(s): {missing}")
    elif data_dir is not None:
        paths = psm_split_paths(data_dir)
    else:
        raise DataError("give data_dir or train and test logs")
    one = read_psm_log(paths["train"], cutoff_hz=cutoff_hz)
    two = read_psm_log(paths["test"], cutoff_hz=cutoff_hz)
    if smoothing == "cv":
        eps, cv_scores = select_smoothing(one, candidates, method=methods[0], bodies=bodies, drives=drives)
    else:
        eps, cv_scores = float(smoothing), {}
    s = psm_structure(bodies=bodies, drives=drives, coulomb_smoothing=eps)
    names = s.row_names
    y_test, y_raw = s.target(two), two.extras["tau_raw"]
    report: dict = {"coordinates": names, "identified": {}, "settings": {}}

    def add(name: str, params: np.ndarray, extra: dict | None = None) -> None:
        pred_tr, pred_te = s.torques(params, one), s.torques(params, two)
        m_te = torque_metrics(y_test, pred_te, names)
        m_raw = torque_metrics(y_raw, pred_te, names)
        m_tr = torque_metrics(s.target(one), pred_tr, names)
        report["identified"][name] = {
            "test_nrmse": _table(names, m_te.nrmse),
            "test_nrmse_raw_effort": _table(names, m_raw.nrmse),
            "test_rel_rms": _table(names, m_te.rel_rms),
            "train_nrmse": _table(names, m_tr.nrmse),
            **(extra or {}),
        }

    results = {} if results is None else results
    for method in methods:
        res = identify(s, one, method=method)
        results[method] = res
        add(method, res.parameters, {"rank": res.diagnostics["rank"], "condition_number": res.diagnostics["condition_number"]})
    if lmi is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the massless-prior note is in the diagnostics
            res = identify(s, one, method="lmi", **lmi)
        results["lmi"] = res
        summ = res.diagnostics.get("lmi", {})
        add("lmi", res.parameters, {k: summ[k] for k in ("solver", "status", "consistent") if k in summ})
    if "params" in paths:
        s_pub = psm_structure(bodies="authors", drives="authors", coulomb_smoothing=0.0)
        p_pub = published_parameters(s_pub, paths["params"])
        pub_te = s_pub.torques(p_pub, two)
        report["published"] = {
            "test_nrmse": _table(names, torque_metrics(y_test, pub_te, names).nrmse),
            "test_nrmse_raw_effort": _table(names, torque_metrics(y_raw, pub_te, names).nrmse),
            "test_rel_rms": _table(names, torque_metrics(y_test, pub_te, names).rel_rms),
            "train_nrmse": _table(names, torque_metrics(s_pub.target(one), s_pub.torques(p_pub, one), names).nrmse),
            "note": "authors' params.json mapped with published_parameters (CoM inertia, sign Coulomb)",
        }
    report["settings"] = {
        "train": str(paths["train"]),
        "test": str(paths["test"]),
        "cutoff_hz": cutoff_hz,
        "filter": "zero-phase Butterworth order 4 on q, v, effort; a = central difference of filtered v",
        "coulomb_smoothing": eps,
        "coulomb_smoothing_cv_scores": cv_scores,
        "bodies": bodies,
        "drives": drives,
        "n_params": s.n_params,
        "n_train": len(one),
        "n_test": len(two),
        "seconds": time.perf_counter() - t0,
        "versions": versions(),
    }
    return report


# ---- simulated payload sessions on a real trajectory ----------------------------------------
SESSION_OFFSET = np.array([0.0, 0.075, 0.0, 0.0, 0.0, 0.0, 0.0])
"""Torque offset between two recording sessions: the mean τ2 shift of 0.075 N·m seen between
``one_results`` (2018) and ``one_no_weight_results`` (2019), same trajectory."""


def ar1_noise(n: int, std: np.ndarray, corr_seconds: float, dt: float, rng: np.random.Generator) -> np.ndarray:
    """Stationary AR(1) noise (n, len(std)): e_k = ρ e_{k−1} + √(1 − ρ²) σ w_k, ρ = exp(−dt/τ)."""
    std = np.asarray(std, float)
    rho = float(np.exp(-dt / corr_seconds)) if corr_seconds > 0 else 0.0
    w = rng.normal(size=(n, std.size)) * std * np.sqrt(1.0 - rho**2)
    from scipy.signal import lfilter

    e0 = rng.normal(size=std.size) * std
    return lfilter([1.0], [1.0, -rho], w, axis=0, zi=(rho * e0)[None, :])[0]


def paired_payload_logs(
    structure,
    params: np.ndarray,
    motion: Trajectory,
    payload,
    frame: str,
    *,
    noise_std: np.ndarray,
    corr_seconds: float = 0.1,
    offset: np.ndarray = SESSION_OFFSET,
    repeat_dq: float = 0.004,
    seed: int = 0,
) -> tuple[Trajectory, Trajectory]:
    """(no-load log, payload log) of one trajectory, as two sessions of a real robot.

    The no-load log replays ``motion`` (θ, θ̇, θ̈); the payload log replays it again with a
    smooth repeat error of amplitude ``repeat_dq`` per coordinate (a tracking controller
    never repeats exactly). Efforts: the model ``structure`` with ``params`` (the "true
    robot"), plus the payload (``pin.Inertia`` in ``frame``) through
    :func:`~sensorless.identification.payload.payload_regressor` in the second log, plus AR(1)
    noise (``noise_std`` per coordinate, correlation time ``corr_seconds``) in both and the
    session ``offset`` in the second. Joint names are the structure's coordinates.
    """
    from sensorless.identification.payload_model import payload_regressor

    rng = np.random.default_rng(seed)
    th, thd, thdd = structure.state(motion)
    t = motion.t - motion.t[0]
    n, k = th.shape
    freq = rng.uniform(0.05, 0.3, k)
    phase = rng.uniform(0, 2 * np.pi, k)
    w = 2 * np.pi * freq
    d = repeat_dq * np.sin(w * t[:, None] + phase)
    dd, ddd = repeat_dq * w * np.cos(w * t[:, None] + phase), -repeat_dq * w**2 * np.sin(w * t[:, None] + phase)
    th2, thd2, thdd2 = th + d, thd + dd, thdd + ddd
    dt = float(np.median(np.diff(motion.t)))
    tau0 = structure.evaluate(th, thd, thdd) @ params + ar1_noise(n, noise_std, corr_seconds, dt, rng)
    phi = payload.toDynamicParameters()
    tau1 = (structure.evaluate(th2, thd2, thdd2) @ params + payload_regressor(structure.robot, th2, thd2, thdd2, frame) @ phi
            + np.asarray(offset, float) + ar1_noise(n, noise_std, corr_seconds, dt, rng))
    names = tuple(structure.coordinates) if hasattr(structure, "coordinates") else tuple(structure.robot.joint_names)
    base = Trajectory(t=motion.t.copy(), q=th, joint_names=names, v=thd, a=thdd, tau=tau0, source="<simulated no-load session>")
    return base, base.with_(q=th2, v=thd2, a=thdd2, tau=tau1, source="<simulated payload session>")


def write_psm_csv(traj: Trajectory, path: str | Path) -> Path:
    """A log in the WPI format: header-less CSV, 21 columns q, q̇, effort of the 7 coordinates."""
    path = Path(path)
    np.savetxt(path, np.hstack([traj.q, traj.v, traj.tau]), delimiter=",", fmt="%.10g")
    return path
