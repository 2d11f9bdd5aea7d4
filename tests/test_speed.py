"""Fast paths against the straightforward ones (issue 13 items 3–4). No timing assertions here:
timings live in ``sensorless benchmark speed`` (studies/benchmarks/results/speed.json).

* SYRK fold == dense MᵀM; the per-row subtree fold == the fold of the assembled regressor;
  the overlapped (threaded) compression == the sequential one.
* Contact null-space fold == projector fold (normal equations and solution, 1e-9 relative).
* Start-up: ``import sensorless.cli`` (all ``--help`` needs) loads no NumPy, SciPy, torch,
  matplotlib, cvxpy, Pinocchio or ``sensorless.data`` (the commands import them when they run); ``load_robot`` builds example-robot-data models once, without meshes.
* ``identify --no-plot`` writes no torques.png.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from sensorless_studies.benchmarks.identify import FEET, contact_log
from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.data.trajectory import Trajectory
from sensorless.excitation import random_fourier
from sensorless.identification import identify
from sensorless.identification.base import random_states
from sensorless.regressor import ContactStructure, ModelStructure, NormalEquations, compress
from sensorless.regressor.normal_equations import syrk_fold
from sensorless.regressor.contact_kinematics import null_space_basis, null_space_projector
from sensorless.testing import perturbed_truth, synthetic_trajectory


def _rel(a, b) -> float:
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / max(np.abs(np.asarray(b)).max(), 1e-300))


# ---- compression --------------------------------------------------------------------------
def test_syrk_fold_equals_dense_product():
    rng = np.random.default_rng(0)
    M = rng.normal(size=(300, 17))
    assert _rel(syrk_fold(M), M.T @ M) < 1e-13
    S = rng.normal(size=(300, 40))[:, ::2]  # non-contiguous input
    assert _rel(syrk_fold(S), S.T @ S) < 1e-13
    assert np.array_equal(syrk_fold(np.zeros((0, 5))), np.zeros((5, 5)))


@pytest.mark.parametrize("name", ["ur5", "solo12"])
def test_subtree_columns_are_structural_zeros_and_the_blockwise_fold_is_exact(request, name):
    """Row r of Pinocchio's regressor is zero outside the subtree columns (oracle: Pinocchio itself),
    and the per-row SYRK fold equals the fold of the assembled regressor (Solo12 in flight: a tree)."""
    robot = request.getfixturevalue(name)
    s = ModelStructure(robot)
    rng = np.random.default_rng(1)
    Q, V, A = random_states(s, 200, rng)
    W = s.evaluate(Q, V, A)
    for r, (c0, c1) in enumerate(s.row_body_columns()):
        outside = np.r_[0:c0, c1 : s.n_body_params]
        assert not np.any(W[:, r, outside])
    y = rng.normal(size=(len(Q), s.n_rows))
    dense, blocks = NormalEquations.zeros(s.n_rows, s.n_params), NormalEquations.zeros(s.n_rows, s.n_params)
    dense.add(W, y)
    blocks.add_blocks(s.body_regressor(Q, V, A), s.joint_features(V, A), s.actuated_rows, y, s.row_body_columns())
    for f in ("A", "b", "c", "y_min", "y_max", "y_sum"):
        assert _rel(getattr(blocks, f), getattr(dense, f)) < 1e-12, f


def test_overlapped_compression_equals_sequential_and_dense(ur5):
    s = ModelStructure(ur5)
    truth = perturbed_truth(ur5, rng=0)
    log = synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(200, 5.0), noise_std=0.1, rng=2)
    seq = compress(s, log, chunk=97, overlap=False)
    ovl = compress(s, log, chunk=97, overlap=True)
    dense = NormalEquations.zeros(s.n_rows, s.n_params)
    keep = s.fit_mask(s.state(log)[1])  # the equations left out of the fit (velocity reversals), whole-log
    assert keep is not None and (keep == 0).any()
    dense.add(s.regressor(log) * keep[:, :, None], s.target(log) * keep)
    for ne in (seq, ovl):
        for f in ("A", "b", "c"):
            assert _rel(getattr(ne, f), getattr(dense, f)) < 1e-12, f
        assert ne.n_samples == len(log)


# ---- contact null-space fold ----------------------------------------------------------------
def test_null_space_basis_spans_the_projector_and_flags_dependent_rows():
    rng = np.random.default_rng(2)
    J = rng.normal(size=(50, 6, 18))
    J[:5, 4] = J[:5, 1]  # dependent rows: the basis misses a null direction
    B, exact = null_space_basis(J, 1e-7)
    assert B.shape == (50, 18, 12)
    assert np.abs(J @ B).max() < 1e-12
    assert np.abs(B.transpose(0, 2, 1) @ B - np.eye(12)).max() < 1e-12
    assert not exact[:5].any() and exact[5:].all()
    P = null_space_projector(J[5:], 1e-7)
    assert np.abs(B[5:] @ B[5:].transpose(0, 2, 1) - P).max() < 1e-9
    B0, e0 = null_space_basis(np.zeros((3, 0, 18)))
    assert e0.all() and np.array_equal(B0[0], np.eye(18))


def test_null_space_fold_gives_the_projected_normal_equations_and_solution(solo12, monkeypatch):
    """Same Σ WᵀPW, Σ WᵀPy, Σ yᵀPy and the same least-squares solution as the 18-row projector fold,
    through both paths of the fold: the basis, and the projector where the basis is not exact (a foot
    listed twice: dependent rows). Stance, trot pairs and flight (B = I)."""
    import sensorless.regressor.contact as contact

    frames = FEET + ("FL_FOOT",)
    ns = ContactStructure(solo12, contact_frames=frames)
    pr = ContactStructure(solo12, contact_frames=frames, fold_basis="projector")
    log = contact_log(solo12, ContactStructure(solo12, contact_frames=FEET), 600, seed=3)
    flags = log.extras["contact"].copy()
    flags[-40:] = False
    twice = flags[:, :1] & (np.arange(len(log)) % 3 == 0)[:, None]
    log = log.with_(extras={"contact": np.hstack([flags, twice])})
    fallback = []
    real = contact.null_space_projector
    monkeypatch.setattr(contact, "null_space_projector", lambda J, *a: fallback.append(len(J)) or real(J, *a))
    a = compress(ns, log, chunk=128)
    n_fallback = sum(fallback)
    assert 0 < n_fallback < len(log) - 40, n_fallback
    b = compress(pr, log, chunk=128)
    (A1, b1, c1), (A0, b0, c0) = a.total(), b.total()
    assert _rel(A1, A0) < 1e-9 and _rel(b1, b0) < 1e-9 and abs(c1 - c0) < 1e-9 * c0
    for f in ("y_min", "y_max", "y_sum"):
        assert _rel(getattr(a, f), getattr(b, f)) < 1e-9, f
    assert a.n_samples == b.n_samples == len(log)
    x1 = identify(ns, a, method="svd", weights=None).parameters  # per-row σ: pooled rows vs joints
    x0 = identify(pr, b, method="svd", weights=None).parameters
    assert np.linalg.norm(x1 - x0) < 1e-9 * np.linalg.norm(x0)
    assert ContactStructure.from_settings(solo12, pr.settings()).fold_basis == "projector"


# ---- start-up and loading ----------------------------------------------------------------------
def test_cli_import_loads_no_heavy_package():
    code = ("import sys, sensorless.cli; heavy = ['numpy', 'scipy', 'torch', 'matplotlib', "
            "'cvxpy', 'pinocchio', 'sensorless.data', 'sensorless.io']; print([m for m in heavy if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", out


def test_a_command_defers_the_numpy_modules_scipy_would_load_unused():
    """Issue 28: SciPy's import copies every public NumPy name, loading numpy.f2py and numpy.testing
    (~0.05 s); a command registers them as lazy modules first. Their code runs only on first use, and
    then gives the same objects to NumPy, SciPy's copy and an import."""
    code = ("import sys\nfrom sensorless.cli.startup import before_scipy\nbefore_scipy()\nimport scipy.linalg\n"
            "ran = sorted(m for m in sys.modules if m.startswith(('numpy.testing.', 'numpy.f2py.', 'unittest')))\n"
            "import numpy, numpy.testing as t, scipy._lib.array_api_compat.numpy as xp\n"
            "t.assert_allclose(scipy.linalg.solve(numpy.eye(2), [1.0, 2.0]), [1.0, 2.0])\n"
            "print(ran, xp.testing is numpy.testing is t, xp.f2py is numpy.f2py, 'numpy.testing._private.utils' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["[]", "True", "True", "True"], out.stdout


def test_the_executable_collects_garbage_less_often_and_a_library_user_keeps_the_defaults():
    """Issue 28: the `sensorless` executable (and `python -m sensorless`) raises the cyclic GC's
    thresholds before the CLI's imports (~145 collections, ~0.04 s of an OLS identify); importing the
    CLI as a library changes nothing, nor does `sensorless stream`."""
    from sensorless.__main__ import GC_THRESHOLDS

    report = "import atexit, gc, sys\natexit.register(lambda: print(gc.get_threshold()))\n"
    run = subprocess.run([sys.executable, "-c", report + "sys.argv = ['sensorless', '--version']\n"
                          "from sensorless.__main__ import main\nmain()"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split("\n")[:2] == ["sensorless " + __import__("sensorless").__version__, str(GC_THRESHOLDS)]
    default = subprocess.run([sys.executable, "-c", "import gc; print(gc.get_threshold())"], capture_output=True,
                             text=True).stdout.strip()  # the interpreter's own
    lib = subprocess.run([sys.executable, "-c", report + "import sensorless.cli, sensorless.__main__"],
                         capture_output=True, text=True)
    assert lib.returncode == 0 and lib.stdout.strip() == default, lib.stderr + lib.stdout
    # the real-time loop keeps the interpreter's collector (short pauses)
    rt = subprocess.run([sys.executable, "-c", report + "sys.argv = ['sensorless', 'stream', '--help']\n"
                         "from sensorless.__main__ import main\nmain()"], capture_output=True, text=True)
    assert rt.returncode == 0 and rt.stdout.strip().splitlines()[-1] == default, rt.stderr + rt.stdout
    module = subprocess.run([sys.executable, "-m", "sensorless", "--version"], capture_output=True, text=True)
    assert module.returncode == 0 and module.stdout.startswith("sensorless "), module.stderr


def test_lazy_exports_resolve_and_list():
    code = ("import sys, sensorless, sensorless.identification as ident, sensorless.data as data, sensorless.robots as rb; "
            "assert 'cvxpy' not in sys.modules; f = ident.solve_lmi; assert 'cvxpy' not in sys.modules; "
            "assert callable(sensorless.load_robot) and sensorless.Trajectory is data.Trajectory; "
            "assert callable(data.base_acceleration) and callable(data.resample) and callable(data.prepare); "
            "assert 'psm_robot' in dir(rb) and set(sensorless.__all__) <= set(dir(sensorless)); "
            "missing = [n for m in (sensorless, ident, data, rb) for n in m.__all__ if not hasattr(m, n)]; print(missing)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stderr + out.stdout


@pytest.mark.parametrize("name", ["ur5", "solo12", "talos"])
def test_example_robot_data_model_is_built_once_without_geometry(monkeypatch, name):
    """Regression: load_robot("ur5") built the model with its meshes twice. Now the URDF is read once
    by path, and the model equals example-robot-data's (inertias, limits, armature, names)."""
    import example_robot_data as erd
    from pinocchio.robot_wrapper import RobotWrapper

    from sensorless import load_robot

    ref = erd.load(name).model
    calls = []
    monkeypatch.setattr(RobotWrapper, "BuildFromURDF", staticmethod(lambda *a, **k: calls.append(a)))
    built = []
    orig = pin.buildModelFromUrdf
    monkeypatch.setattr(pin, "buildModelFromUrdf", lambda *a: built.append(a[0]) or orig(*a))
    r = load_robot(name)
    assert calls == [] and len(built) == 1 and r.urdf_path == built[0]
    m = r.model
    assert list(m.names) == list(ref.names) and m.nq == ref.nq
    for a, b in zip(m.inertias, ref.inertias):
        assert np.allclose(a.toDynamicParameters(), b.toDynamicParameters())
    for f in ("armature", "upperPositionLimit", "lowerPositionLimit", "velocityLimit", "effortLimit"):
        assert np.allclose(getattr(m, f), getattr(ref, f)), f


def test_cli_commands_run_blas_on_one_thread(monkeypatch):
    from threadpoolctl import threadpool_info

    from sensorless.cli.blas import BLAS_ENV, blas_threads_for_command

    for v in BLAS_ENV:
        monkeypatch.delenv(v, raising=False)
    before = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    with blas_threads_for_command():
        assert all(i["num_threads"] == 1 for i in threadpool_info() if i["user_api"] == "blas")
    assert [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"] == before


# ---- identify --no-plot ------------------------------------------------------------------------
def test_identify_no_plot_writes_no_png_and_the_plot_is_a_decimated_window(ur5, tmp_path):
    truth = perturbed_truth(ur5, rng=0)
    log = synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(200, 10.0), noise_std=0.1, rng=2)
    f = write_npz(log, tmp_path / "log.npz")
    runner = CliRunner()
    r = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(f), "--out", str(tmp_path / "a"), "--no-plot"])
    assert r.exit_code == 0, r.output
    assert not (tmp_path / "a" / "torques.png").exists() and (tmp_path / "a" / "result.json").exists()
    r = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(f), "--out", str(tmp_path / "b")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "b" / "torques.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "a" / "result.json").read_text())["parameters"]


def test_plot_window_predicts_only_the_decimated_samples(ur5, tmp_path, monkeypatch):
    import sensorless.run.figures as core

    truth = perturbed_truth(ur5, rng=0)
    log = synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(1000, 30.0), noise_std=0.1, rng=2)
    assert len(log) > core.PLOT_WINDOW
    seen = {}

    class Model:
        def predict(self, traj: Trajectory):
            seen["n"], seen["t_end"] = len(traj), float(traj.t[-1])
            return np.zeros((len(traj), 6))

    import sensorless.report as report

    monkeypatch.setattr(report, "plot_torques_by_limb", lambda t, meas, preds, *a, **k: seen.update(points=len(t)) or {})
    core.plot_window(log, ModelStructure(ur5), {"M": Model()}, tmp_path, "t")
    assert seen["n"] == seen["points"] <= core.PLOT_POINTS
    assert seen["t_end"] < log.t[core.PLOT_WINDOW]


def test_blockwise_fold_on_a_tree_numbered_breadth_first():
    """Regression: the subtree columns assumed depth-first numbering (an assertion error on the
    PSM's coded tree). Joint 4 hangs under joint 2 after sibling 3: the range is a superset, still exact."""
    from sensorless.robot import Robot

    m = pin.Model()
    parents = {1: 0, 2: 1, 3: 1, 4: 2}
    rng = np.random.default_rng(5)
    for j, par in parents.items():
        jid = m.addJoint(par, pin.JointModelRY() if j % 2 else pin.JointModelRZ(),
                         pin.SE3(np.eye(3), rng.normal(size=3) * 0.3), f"j{j}")
        m.appendBodyToJoint(jid, pin.Inertia.Random(), pin.SE3.Identity())
    m.lowerPositionLimit, m.upperPositionLimit = -np.pi * np.ones(m.nq), np.pi * np.ones(m.nq)
    m.velocityLimit, m.effortLimit = 3.0 * np.ones(m.nv), 50.0 * np.ones(m.nv)
    s = ModelStructure(Robot(m, name="tree"))
    assert s.row_body_columns()[1] == (10, 40)  # subtree of j2 = {2, 4}: columns 10..40 include j3's zeros
    Q, V, A = random_states(s, 100, rng)
    W = s.evaluate(Q, V, A)
    y = rng.normal(size=(100, s.n_rows))
    dense, blocks = NormalEquations.zeros(s.n_rows, s.n_params), NormalEquations.zeros(s.n_rows, s.n_params)
    dense.add(W, y)
    blocks.add_blocks(s.body_regressor(Q, V, A), s.joint_features(V, A), s.actuated_rows, y, s.row_body_columns())
    assert _rel(blocks.A, dense.A) < 1e-12 and _rel(blocks.b, dense.b) < 1e-12


def test_benchmark_speed_refuses_an_unknown_part():
    r = CliRunner().invoke(app, ["benchmark", "speed", "--parts", "contact,warp"])
    assert r.exit_code == 2 and "warp" in r.output and "startup" in r.output
