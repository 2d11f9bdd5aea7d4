"""The robot registry (sensorless.robots.registry): the names load_robot accepts, each loading the same
robot as its direct construction; options that do not apply to a robot built in code are refused."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.errors import RobotModelError
from sensorless.robot import load_robot
from sensorless.robots.base import RobotEntry
from sensorless.robots.registry import ROBOTS, find_robot, robot_names


def test_registry_is_consistent():
    names = robot_names()
    assert len(names) == len(set(names)) and "dvrk_psm" in names and "ur5" in names
    for e in ROBOTS:
        assert isinstance(e, RobotEntry) and e.description
        for n in e.names:
            assert find_robot(n) is e
    assert find_robot("DVRK_PSM").names[0] == "dvrk_psm" and find_robot("no_such_robot") is None


def test_a_robot_built_in_code_loads_by_name_as_built():
    from sensorless.robots.dvrk_psm import COORDINATES, PSM_LIMITS, psm_robot

    direct, r = psm_robot(), load_robot("dvrk_psm")
    assert r.coupled and r.joint_names == direct.joint_names == COORDINATES
    np.testing.assert_array_equal(r.transmission_matrix, direct.transmission_matrix)
    np.testing.assert_array_equal(r.inertial_parameters(), direct.inertial_parameters())
    assert r.excitation_box is PSM_LIMITS and r.make_structure().n_params == direct.make_structure().n_params
    with pytest.raises(RobotModelError, match=r"built in code: it does not take `lock_joints`, `passive_joints`"):
        load_robot("psm", lock_joints=["q1"], passive_joints=["q2"])


def test_an_example_robot_data_name_loads_its_urdf_model():
    from sensorless.robots.erd_robots import erd_model

    r = load_robot("ur5")
    model, urdf = erd_model("ur5")
    ref = pin.buildModelFromUrdf(urdf)
    assert not r.coupled and r.excitation_box is None and r.urdf_path == urdf
    assert list(r.model.names) == list(ref.names)
    np.testing.assert_array_equal(r.inertial_parameters(),
                                  np.concatenate([ref.inertias[j].toDynamicParameters() for j in range(1, ref.njoints)]))


def test_an_unknown_name_lists_the_registry():
    with pytest.raises(RobotModelError, match=r"nor a registered robot name; did you mean 'ur5'.*dvrk_psm"):
        load_robot("ur55")
