"""The streamed identification of long logs (chunked readers, chunked preprocessing, one fold pass)
gives the whole-log path's samples, equations and parameters, and names the sample of bad data."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data.chunks import open_chunked
from sensorless.data.periodicity import excitation_period
from sensorless.data.prepare import load_log
from sensorless.data.streamed_log import scan_log
from sensorless.errors import NonFiniteError, TimestampError
from sensorless.excitation import random_fourier
from sensorless.identification.friction import friction_structure
from sensorless.identification.stribeck import StribeckCandidates
from sensorless.identification.streamed import fold_stream, streamed_friction, streamed_identify
from sensorless.regressor import ModelStructure, compress
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth, streamed_fourier_log

runner = CliRunner()
N = 12_000
N_CLEAN = 18_000


@pytest.fixture(scope="module")
def ur5():
    return load_robot("ur5")


def _log(robot, n=N, seed=0, rest=None):
    """A UR5 Fourier log at 1 kHz (arrays t, q, dq, tau) with velocity noise; ``rest``: a (start, stop)
    stretch held still (q constant plus noise, v noise) to exercise the rest detection."""
    truth = perturbed_truth(robot, rng=seed)
    parts = list(streamed_fourier_log(truth, random_fourier(robot, rng=seed + 1, base_freq=0.1), rate=1000.0,
                                      n_samples=n, noise_std=0.1, rng=seed))
    cat = lambda k: np.concatenate([getattr(p, k) for p in parts])  # noqa: E731
    rng = np.random.default_rng(seed + 7)
    t, q, v, tau = cat("t"), cat("q"), cat("v"), cat("tau")
    v = v + rng.normal(scale=2e-3, size=v.shape)
    if rest is not None:
        a, b = rest
        q[a:b] = q[a]
        q[a:b, 1] += 2e-4 * (t[a:b] - t[a])  # joint 2 creeps at 2e-4 rad/s (seen in q, lost in v's noise)
        q += rng.normal(scale=1e-4, size=q.shape)
        v[a:b] = rng.normal(scale=2e-3, size=v[a:b].shape)
    return {"t": t, "q": q, "dq": v, "tau": tau}


@pytest.fixture(scope="module")
def logs(tmp_path_factory, ur5):
    d = tmp_path_factory.mktemp("streamed")
    arrays = _log(ur5, rest=(3000, 4200))
    np.savez(d / "log.npz", **arrays)
    np.savez_compressed(d / "zipped.npz", **arrays)
    np.savez(d / "clean.npz", **_log(ur5, n=N_CLEAN, seed=3))  # > 1/0.6 periods of 10 s: folds on whole periods
    return d, arrays


def _same_rows(a, b, tol=1e-10):
    scale = max(np.abs(b).max(), 1.0)
    assert np.abs(a - b).max() <= tol * scale


def test_readers_give_the_logged_arrays(logs, ur5, tmp_path):
    pytest.importorskip("pyarrow")
    h5py = pytest.importorskip("h5py")
    import pandas as pd

    d, arr = logs
    with h5py.File(tmp_path / "log.h5", "w") as h:
        for k, x in arr.items():
            h[k] = x
    cols = {"t": arr["t"]}
    for fld, key in (("q", "q"), ("v", "dq"), ("tau", "tau")):
        cols.update({f"{fld}_{j}": arr[key][:, k] for k, j in enumerate(ur5.joint_names)})
    pd.DataFrame(cols).to_parquet(tmp_path / "log.parquet")
    for path in (d / "log.npz", d / "zipped.npz", tmp_path / "log.h5", tmp_path / "log.parquet"):
        log = open_chunked(path, ur5.joint_names)
        assert log is not None and log.n_samples == N, path
        got = {f: [] for f in ("t", "q", "v", "tau")}
        for s, part in log.chunks(list(got), 1999, start=17, stop=N - 5):
            for f in got:
                got[f].append(part[f])
        for f, key in (("t", "t"), ("q", "q"), ("v", "dq"), ("tau", "tau")):
            assert np.array_equal(np.concatenate(got[f]), arr[key][17 : N - 5]), (path, f)


def test_chunked_preprocessing_equals_the_whole_log(logs, ur5):
    d, _ = logs
    whole = load_log(d / "log.npz", ur5, None, None, None, None, 1)
    slog = scan_log(open_chunked(d / "log.npz", ur5.joint_names))
    assert whole.provenance["rest"]["fraction_at_rest"] == slog.provenance["rest"]["fraction_at_rest"]
    assert max(whole.provenance["rest"]["fraction_creeping"].values()) > 0  # the creep path is exercised
    for size in (37, 100, 101, 1000, 4097, N):  # below, at and above the half window (100 samples)
        v, a = [], []
        for s, n, part in slog.chunks(size):
            assert len(part) == n + (s + n < N)  # the look-ahead sample
            v.append(part.v[:n])
            a.append(part.a[:n])
        _same_rows(np.concatenate(v), whole.v)
        _same_rows(np.concatenate(a), whole.a)
    s0 = ModelStructure(ur5, joint_terms=("fv", "fc", "stribeck", "offset", "armature"))
    _, law = friction_structure(s0, [whole])
    _, mine = streamed_friction(s0, slog)
    assert law.coulomb_smoothing == mine.coulomb_smoothing and law.stribeck_grid == mine.stribeck_grid
    assert law.width_grid == mine.width_grid and law.torque_noise == mine.torque_noise


@pytest.mark.parametrize("candidates", [False, True])
def test_chunked_compression_equals_the_whole_log(logs, ur5, candidates):
    d, _ = logs
    whole = load_log(d / "log.npz", ur5, None, None, None, None, 1)
    slog = scan_log(open_chunked(d / "log.npz", ur5.joint_names))
    s0 = ModelStructure(ur5, joint_terms=("fv", "fc", "stribeck", "offset", "armature"))
    _, law = friction_structure(s0, [whole])
    s, _ = friction_structure(s0, [], coulomb_smoothing=law.coulomb_smoothing, stribeck_velocity=law.stribeck_grid,
                              width_grid=law.width_grid)
    st = StribeckCandidates(s, law.stribeck_grid, law.width_grid) if candidates else s
    ref = compress(st, whole, chunk=2048)
    for chunk, folds in ((333, 1), (2048, 5)):
        nes = fold_stream(st, slog, n_folds=folds, chunk=chunk, overlap=chunk == 333)
        assert len(nes) == folds and sum(ne.n_samples for ne in nes) == N
        _sum_is(nes, ref, candidates)


def _sum_is(folds, ref, left_out: bool) -> None:
    """The folds' equations add up to ``ref`` (and their left-out equations too)."""
    tot = folds[0]
    for ne in folds[1:]:
        tot = tot.merge(ne)
    for x, y in ((tot.A, ref.A), (tot.b, ref.b), (tot.c, ref.c), (tot.y_min, ref.y_min), (tot.y_max, ref.y_max)):
        _same_rows(x, y)
    if left_out:
        _same_rows(tot.left_out.A, ref.left_out.A)


def test_streamed_equations_with_and_without_the_kernel_agree(logs, ur5, monkeypatch):
    """The C++ kernels (regressor into the row-major chunk, candidate columns) against the NumPy/Pinocchio
    route (SENSORLESS_NATIVE=0): the same equations, fold by fold and left out, at odd chunk boundaries."""
    from sensorless.regressor import native

    d, _ = logs
    slog = scan_log(open_chunked(d / "log.npz", ur5.joint_names))
    s0 = ModelStructure(ur5, joint_terms=("fv", "fc", "stribeck", "offset", "armature"))
    _, law = streamed_friction(s0, slog)
    s, _ = friction_structure(s0, [], coulomb_smoothing=law.coulomb_smoothing, stribeck_velocity=law.stribeck_grid,
                              width_grid=law.width_grid)
    st = StribeckCandidates(s, law.stribeck_grid, law.width_grid)
    got = fold_stream(st, slog, n_folds=5, chunk=333, overlap=True)
    monkeypatch.setenv("SENSORLESS_NATIVE", "0")
    native._lib.cache_clear()
    try:
        assert not native.available()
        ref = fold_stream(st, slog, n_folds=5, chunk=1000, overlap=False)
    finally:
        monkeypatch.delenv("SENSORLESS_NATIVE")
        native._lib.cache_clear()
    for a, b in zip(got, ref):
        assert a.n_samples == b.n_samples and a.left_out.n_samples == b.left_out.n_samples > 0
        for x, y in ((a.A, b.A), (a.b, b.b), (a.c, b.c), (a.left_out.A, b.left_out.A), (a.left_out.b, b.left_out.b)):
            _same_rows(x, y)


@pytest.mark.parametrize("candidates", [False, True])
def test_cross_validation_folds_are_the_streamed_folds(logs, ur5, candidates):
    """The whole-log folds of ``--gamma auto`` (one pass, phase blocks) equal the streamed pass's fold by
    fold, and sum to the whole log's equations: the masks of the fit (reversals, rest) are the whole
    log's in both, not those of a fold's samples cut out of it."""
    from sensorless.identification.gamma import split_folds

    d, _ = logs
    whole = load_log(d / "clean.npz", ur5, None, None, None, None, 1)
    slog = scan_log(open_chunked(d / "clean.npz", ur5.joint_names))
    assert slog.period is not None  # phase blocks: a fold's samples are not contiguous
    s0 = ModelStructure(ur5, joint_terms=("fv", "fc", "stribeck", "offset", "armature"))
    _, law = friction_structure(s0, [whole])
    s, _ = friction_structure(s0, [], coulomb_smoothing=law.coulomb_smoothing, stribeck_velocity=law.stribeck_grid,
                              width_grid=law.width_grid)
    st = StribeckCandidates(s, law.stribeck_grid, law.width_grid) if candidates else s
    assert st.fit_mask(whole.v) is not None and not st.fit_mask(whole.v).all()  # masks are exercised
    folds = split_folds(st, [whole], 5, 2048, slog.period)
    streamed = fold_stream(st, slog, n_folds=5, chunk=2048)
    for a, b in zip(folds, streamed):
        assert a.n_samples == b.n_samples
        for x, y in ((a.A, b.A), (a.b, b.b), (a.c, b.c)):
            _same_rows(x, y)
    _sum_is(folds, compress(st, whole, chunk=2048), candidates)


def _identify(args, out):
    res = runner.invoke(app, ["identify", "--robot", "ur5", "--out", str(out), "--no-plot", *args])
    assert res.exit_code == 0, res.output
    return json.loads((out / "result.json").read_text())


@pytest.mark.parametrize("method", [["--method", "ols"], ["--method", "lmi", "--gamma", "0.001"]])
def test_cli_streamed_equals_in_memory(logs, tmp_path, method):
    d, _ = logs
    data = ["--data", str(d / "clean.npz"), *method]
    a = _identify([*data, "--stream"], tmp_path / "s")
    b = _identify([*data, "--no-stream"], tmp_path / "m")
    assert a["settings"]["streamed"]["n_samples"] == N_CLEAN and "streamed" not in b["settings"]
    pa, pb = (np.array(list(x["parameters"].values())) for x in (a, b))
    # the two passes' sums agree to ~1e-14; the LMI's solutions then to the solver's tolerance (1e-8):
    # the directions the data leave open (a shoulder's mass) are set by γ and the constraints only
    assert np.abs(pa - pb).max() <= (1e-9 if method[1] == "ols" else 1e-8) * np.abs(pb).max()
    assert a["settings"]["friction"]["stribeck_velocity"] == b["settings"]["friction"]["stribeck_velocity"]
    assert a["diagnostics"]["n_samples"] == b["diagnostics"]["n_samples"] == N_CLEAN


def test_cross_validated_gamma_matches(logs, ur5):
    d, _ = logs
    s0 = ModelStructure(ur5, joint_terms=("fv", "fc", "offset"))
    from sensorless.identification import identify

    res = streamed_identify(s0, d / "clean.npz", method="lmi", friction=False, min_samples=0, gamma="auto")
    whole = load_log(d / "clean.npz", ur5, None, None, None, None, 1)
    ref = identify(s0, [whole], method="lmi", gamma="auto")
    assert res.result.diagnostics["gamma"] == ref.diagnostics["gamma"]
    p, q = res.result.parameters, ref.parameters
    assert np.abs(p - q).max() <= 1e-8 * np.abs(q).max()
    period = res.result.settings["streamed"]["fold_period_s"]
    assert period == excitation_period(whole) and period == pytest.approx(10.0, abs=0.05)


def test_nan_in_a_later_chunk_names_the_sample(logs, ur5, tmp_path):
    _, arr = logs
    bad = {k: x.copy() for k, x in arr.items()}
    bad["tau"][9876, 3] = np.nan
    np.savez(tmp_path / "nan.npz", **bad)
    s0 = ModelStructure(ur5)
    with pytest.raises(NonFiniteError, match=r"'tau' column 'wrist_1_joint'.*sample 9876 \(t=9\.876"):
        streamed_identify(s0, tmp_path / "nan.npz", min_samples=0)
    res = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / "nan.npz"), "--stream",
                              "--out", str(tmp_path / "o"), "--no-plot"])
    assert res.exit_code != 0 and "sample 9876" in res.output and not (tmp_path / "o").exists()
    back = {k: x.copy() for k, x in arr.items()}
    back["t"][7001] = back["t"][6999]
    np.savez(tmp_path / "back.npz", **back)
    with pytest.raises(TimestampError, match="backwards at sample 7001 "):
        streamed_identify(s0, tmp_path / "back.npz", min_samples=0)


def test_logs_it_cannot_reproduce_go_to_the_whole_log_path(logs, ur5, tmp_path):
    d, arr = logs
    assert streamed_identify(ModelStructure(ur5), d / "log.npz") is None  # shorter than the default minimum
    glitch = {k: x.copy() for k, x in arr.items()}
    glitch["tau"][500, 0] = 1e9  # a gross outlier: the whole-log path names it
    np.savez(tmp_path / "glitch.npz", **glitch)
    assert scan_log(open_chunked(tmp_path / "glitch.npz", ur5.joint_names)) is None
    np.savez(tmp_path / "extra.npz", **arr, a=np.zeros_like(arr["q"]))  # a logged v̇: read whole
    assert open_chunked(tmp_path / "extra.npz", ur5.joint_names) is None


def test_held_out_scores_and_ols_baseline_match(logs, tmp_path):
    d, _ = logs
    data = ["--data", str(d / "clean.npz"), "--validate", str(d / "log.npz"), "--gamma", "0.001"]
    a = _identify([*data, "--stream"], tmp_path / "s")
    b = _identify([*data, "--no-stream"], tmp_path / "m")
    va, vb = (next(iter(x["validation"].values())) for x in (a, b))
    for col in ("lmi", "ols"):
        assert va[col]["mean_nrmse"] == pytest.approx(vb[col]["mean_nrmse"], rel=1e-7), col


def test_long_log_benchmark_records_each_run(tmp_path):
    """The benchmark's record (not its figures: those are the benchmark's business)."""
    from sensorless_studies.benchmarks.long_log import bench_long_log

    res = bench_long_log([3000, 6000], extra_args=("--stream", "--no-plot", "--gamma", "0.001"), work=tmp_path)
    assert [r["n_samples"] for r in res["runs"]] == [3000, 6000]
    assert all(r["streamed"] and r["peak_rss_mib"] > 50 and r["wall_seconds"] > 0 for r in res["runs"])
    assert res["peak_memory_ratio_largest_over_smallest"] > 0 and "marginal_per_sample_us" in res
    assert res["bare_cpp_regressor_us"] is None or res["bare_cpp_regressor_us"] > 0
    assert not list(tmp_path.iterdir())  # the logs and outputs are removed
