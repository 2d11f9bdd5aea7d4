"""The optional C++ regressor kernel (sensorless.regressor.native): built by `make` wherever a C++
compiler exists, equal to Pinocchio's Python regressor, and compress() gives the same sums with it
as without it."""

from __future__ import annotations

import shutil

import numpy as np
import pinocchio as pin
import pytest

from sensorless.regressor import ModelStructure, compress, native
from sensorless.robot import load_robot

pytestmark = pytest.mark.skipif(not native.available() and shutil.which("g++") is None,
                                reason="no C++ compiler here: the kernel cannot be built (pure-Python path)")


def test_make_built_the_kernel():
    assert native.available(), "run `python -m sensorless.regressor.native_build` (the Makefile does)"


@pytest.mark.parametrize("name", ["ur5", "panda", "solo12"])
def test_kernel_equals_pinocchio_on_random_states(name):
    robot = load_robot(name)
    m = robot.model
    kernel = native.native_regressor(m)
    assert kernel is not None
    rng = np.random.default_rng(1)
    Q = np.array([pin.randomConfiguration(m, -np.ones(m.nq), np.ones(m.nq)) for _ in range(40)])
    V, A = rng.standard_normal((40, m.nv)), rng.standard_normal((40, m.nv))
    rows = np.arange(m.nv)[::-1][: max(m.nv - 2, 1)]  # a row subset, in another order
    out = np.empty((40, rows.size, 10 * (m.njoints - 1)))
    for threads in (1, 3):
        kernel(Q, V, A, rows, out, threads=threads)
        d = m.createData()
        ref = np.array([pin.computeJointTorqueRegressor(m, d, Q[i], V[i], A[i])[rows] for i in range(40)])
        assert np.array_equal(out, ref)


def test_compress_and_regressor_with_and_without_the_kernel_are_identical(monkeypatch):
    from sensorless_studies.benchmarks.speed import fourier_log

    robot = load_robot("ur5")
    traj = fourier_log(robot, 1500)
    s = ModelStructure(robot)
    with_kernel = compress(s, traj, chunk=512)
    W_kernel = s.regressor(next(traj.chunks(100)))  # the full regressor: the body block is a strided view of it
    monkeypatch.setenv("SENSORLESS_NATIVE", "0")
    native._lib.cache_clear()
    try:
        assert not native.available()
        without = compress(s, traj, chunk=512)
        W = s.regressor(next(traj.chunks(100)))
    finally:
        monkeypatch.delenv("SENSORLESS_NATIVE")
        native._lib.cache_clear()
    assert np.array_equal(with_kernel.A, without.A) and np.array_equal(with_kernel.b, without.b)
    assert np.array_equal(W_kernel, W)


def test_kernel_writes_a_row_major_view_as_the_contiguous_buffer():
    """The streamed pass lays chunks out row-major (rows, samples, columns); the kernel writes the
    (samples, rows, body columns) view of such a buffer in place, equal to the contiguous output."""
    robot = load_robot("ur5")
    m = robot.model
    kernel = native.native_regressor(m)
    assert kernel is not None and kernel.strided
    rng = np.random.default_rng(2)
    Q, V, A = rng.standard_normal((33, m.nq)), rng.standard_normal((33, m.nv)), rng.standard_normal((33, m.nv))
    rows = np.array([4, 0, 2])
    ref = kernel(Q, V, A, rows, np.empty((33, 3, 60)))
    for threads in (1, 2):
        wide = np.full((3, 40, 60 + 7), np.nan)
        view = wide[:, 5:38, :60].transpose(1, 0, 2)
        kernel(Q, V, A, rows, view, threads=threads)
        assert np.array_equal(view, ref)
        assert np.isnan(wide[:, :5]).all() and np.isnan(wide[:, 38:]).all() and np.isnan(wide[:, :, 60:]).all()
    with pytest.raises(ValueError, match="shape or layout"):
        kernel(Q, V, A, rows, np.empty((33, 3, 120))[:, :, ::2])  # the columns must be contiguous


def test_unknown_joint_type_falls_back_to_python():
    m = pin.Model()
    j = m.addJoint(0, pin.JointModelSphericalZYX(), pin.SE3.Identity(), "ball")
    m.appendBodyToJoint(j, pin.Inertia.Random(), pin.SE3.Identity())
    assert native.native_regressor(m) is None


def test_bad_buffer_is_refused():
    robot = load_robot("ur5")
    kernel = native.native_regressor(robot.model)
    Q = np.zeros((4, robot.model.nq))
    with pytest.raises(ValueError, match="shape or layout"):
        kernel(Q, Q, Q, np.arange(6), np.empty((4, 6, 59)))


def test_a_failed_build_says_why_and_keeps_the_python_path(monkeypatch, capsys):
    from sensorless.regressor.native_build import main

    before = native.library_path()
    monkeypatch.setenv("CXX", "/nonexistent/c++")
    assert main([]) == 1
    err = capsys.readouterr().err
    assert "not built" in err and "/nonexistent/c++" in err and "pure-Python path" in err
    assert native.library_path() == before  # an existing kernel is left alone
