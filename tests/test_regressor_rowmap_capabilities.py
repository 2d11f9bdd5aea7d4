"""Callers ask the row map what the equations are (issue 15), not the structure's type:
``per_sample`` / ``projected`` / ``measured_wrench`` of each map, and the code paths that read
them (acceleration-free identification, base-wrench checks, the momentum observer)."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.data import Trajectory
from sensorless.errors import DataError, RobotModelError
from sensorless.estimation.momentum import MomentumDynamics
from sensorless.identification.floating_base import base_wrench_metrics
from sensorless.regressor import ContactStructure, ModelStructure
from sensorless.regressor.integral import filtered_rows
from sensorless.robots import psm_structure

FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")


@pytest.mark.parametrize("mode", ["projected", "wrench"])
def test_contact_map_flags(solo12, mode):
    s = ContactStructure(solo12, joint_terms=("fv",), contact_frames=FEET, mode=mode)
    rm = s.row_map
    assert rm.per_sample and not rm.selects_rows
    assert rm.projected == (mode == "projected") and rm.measured_wrench == (mode == "wrench") == s.measured_wrench


def test_constant_maps_neither_project_nor_measure_wrenches(panda, solo12):
    for s in (ModelStructure(panda), ModelStructure(solo12), psm_structure()):
        rm = s.row_map
        assert not (rm.per_sample or rm.projected or rm.measured_wrench or s.measured_wrench)


def _log(robot, n=50):
    rng = np.random.default_rng(5)
    nj = len(robot.joint_names)
    q = rng.normal(size=(n, nj)) * 0.1
    base_q = np.tile([0, 0, 0.3, 0, 0, 0, 1.0], (n, 1))
    return Trajectory(t=np.arange(n) * 0.01, q=q, v=rng.normal(size=(n, nj)), a=np.zeros((n, nj)),
                      tau=rng.normal(size=(n, nj)), base_q=base_q, base_v=np.zeros((n, 6)), base_a=np.zeros((n, 6)),
                      joint_names=robot.joint_names, source="<random>",
                      extras={"contact": np.ones((n, 4), bool), "contact_forces": rng.normal(size=(n, 4, 3))})


def test_code_paths_follow_the_map(solo12):
    tr = _log(solo12)
    wrench = ContactStructure(solo12, joint_terms=("fv",), contact_frames=FEET, mode="wrench")
    projected = ContactStructure(solo12, joint_terms=("fv",), contact_frames=FEET)
    with pytest.raises(RobotModelError, match="mode='projected'"):
        filtered_rows(wrench, tr)
    assert filtered_rows(projected, tr).W.shape == (len(tr), solo12.nv, projected.n_params)
    p = np.zeros(wrench.n_params)
    assert base_wrench_metrics(wrench, p, tr)["n_samples"] == len(tr)
    for s in (projected, ModelStructure(solo12)):
        with pytest.raises(DataError, match="mode 'wrench'"):
            base_wrench_metrics(s, np.zeros(s.n_params), tr)


def test_momentum_observer_takes_the_transmission_path_from_the_robot(panda):
    s = psm_structure()
    assert MomentumDynamics(s, s.prior()).transmission and MomentumDynamics(s, s.prior()).n == len(s.coordinates)
    m = ModelStructure(panda)
    assert not MomentumDynamics(m, m.prior()).transmission
