"""sensorless.run.model: the robot of a run (registry names, files, added frames), its model structure
(per joint, coupled drives, contacts) and the LMI settings; bad options are typed errors naming the field."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from sensorless.cli import app

from sensorless.errors import OptionError, RobotModelError, SensorlessError
from sensorless.regressor import ModelStructure
from sensorless.regressor.contact import ContactStructure
from sensorless.robots.dvrk_psm import psm_robot
from sensorless.run.model import is_plain, lmi_settings, load_run_robot, model_structure, parse_add_frame


def test_dvrk_psm_loads_through_the_registry_and_refuses_joint_options():
    r = load_run_robot("dvrk_psm")
    direct = psm_robot()
    assert r.coupled and r.name == direct.name and list(r.joint_names) == list(direct.joint_names)
    assert load_run_robot("psm").joint_names == r.joint_names  # an alias of the same registry entry
    for kw in (dict(lock=["outer_yaw"]), dict(passive=["outer_yaw"]), dict(floating_base=True)):
        with pytest.raises(RobotModelError, match="dvrk_psm"):
            load_run_robot("dvrk_psm", **kw)


def test_the_command_names_the_flag_a_registry_robot_refuses(tmp_path):
    (tmp_path / "a.npz").touch()
    r = CliRunner().invoke(app, ["identify", "--robot", "dvrk_psm", "--lock", "outer_yaw", "--data",
                                 str(tmp_path / "a.npz"), "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "dvrk_psm" in r.output and "does not take --lock" in r.output, r.output
    assert not (tmp_path / "o").exists()


def test_added_frames_sit_where_the_spec_says(ur5):
    spec = "tcp:tool0:0.01,-0.02,0.15:0,0,1.5707963267948966"
    name, parent, xyz, rpy = parse_add_frame(spec)
    assert (name, parent, xyz, rpy) == ("tcp", "tool0", [0.01, -0.02, 0.15], [0.0, 0.0, np.pi / 2])
    r = load_run_robot("ur5", frames=[parse_add_frame(spec)])
    assert not ur5.model.existFrame("tcp") and r.model.existFrame("tcp")
    q = pin.neutral(r.model) + np.linspace(0.1, 0.6, r.model.nq)
    pin.framesForwardKinematics(r.model, r.data, q)
    tool = r.data.oMf[r.model.getFrameId("tool0")]
    want = tool * pin.SE3(pin.rpy.rpyToMatrix(0, 0, np.pi / 2), np.array([0.01, -0.02, 0.15]))
    assert np.allclose(r.data.oMf[r.model.getFrameId("tcp")].homogeneous, want.homogeneous, atol=1e-12)


@pytest.mark.parametrize("spec", ["tcp:tool0", "tcp:tool0:1,2", "tcp:tool0:a,b,c", ":tool0:0,0,0",
                                  "tcp:tool0:0,0,0:1,2"])
def test_a_bad_frame_spec_names_the_field_and_the_spec(spec):
    with pytest.raises(SensorlessError) as e:
        parse_add_frame(spec)
    assert "`model.add_frame`" in str(e.value) and spec in str(e.value)


def test_frames_on_an_unknown_parent_are_refused():
    with pytest.raises(RobotModelError, match="nowhere"):
        load_run_robot("ur5", frames=[("tcp", "nowhere", [0, 0, 0], [0, 0, 0])])


def test_structure_per_joint_coupled_or_contact(ur5, solo12):
    s = model_structure(ur5, "fv,fc,offset", 0.01, None, None, 0.0, "projected")
    assert type(s) is ModelStructure and is_plain(s)
    assert s.coulomb_smoothing == 0.01 and set(s.joint_terms) == {"fv", "fc", "offset"}
    per_joint = model_structure(ur5, "shoulder_pan_joint=fv;*=fc", 0.0, None, None, 0.0, "projected")
    assert is_plain(per_joint) and per_joint.n_params != s.n_params

    feet = "FL_FOOT,FR_FOOT,HL_FOOT,HR_FOOT"
    c = model_structure(solo12, "fv", 0.0, feet, "3,3,3,3", 0.0, "projected")
    assert isinstance(c, ContactStructure) and not is_plain(c)
    assert tuple(c.contact_frames) == tuple(feet.split(","))

    psm = load_run_robot("dvrk_psm")
    d = model_structure(psm, "motors", 0.0, None, None, 0.0, "projected")  # its drive set, built by the robot
    assert not is_plain(d) and d.row_names == psm.make_structure(("motors",), 0.0).row_names
    with pytest.raises(SensorlessError, match="`model.contact_frames`"):
        model_structure(psm, "fv", 0.0, "tool", None, 0.0, "projected")
    with pytest.raises(OptionError, match="`model.joint_terms`"):
        model_structure(psm, "outer_yaw=fv", 0.0, None, None, 0.0, "projected")


@pytest.mark.parametrize("args, field", [
    (("fv", float("nan"), None, None), "model.coulomb_smoothing"),
    (("fv", 0.0, None, "3"), "model.contact_dims"),
    (("fv,bogus", 0.0, None, None), "model.joint_terms"),
])
def test_bad_structure_options_name_the_field(ur5, args, field):
    terms, eps, frames, dims = args
    with pytest.raises(SensorlessError) as e:
        model_structure(ur5, terms, eps, frames, dims, 0.0, "projected")
    assert f"`{field}" in str(e.value)


def test_lmi_settings(ur5):
    s = model_structure(ur5, "fv", 0.0, None, None, 0.0, "projected")
    assert lmi_settings(ur5, s, "ols", None, "pullback", "auto", "auto", True) == {}
    kw = lmi_settings(ur5, s, "lmi", None, "none", "0.01", "none", True)
    assert kw == {"gamma": 0.01, "regularization": None, "prior": None, "ellipsoids": False}
    kw = lmi_settings(ur5, s, "lmi", "prior.urdf", "pullback", "auto", "auto", True,
                      load_prior=lambda p, floating_base: ur5)
    assert kw["gamma"] == "auto" and kw["ellipsoids"] is None
    assert np.array_equal(kw["prior"][: 10 * len(ur5.body_names)], ur5.inertial_parameters())
    with pytest.raises(SensorlessError, match="`solver.ellipsoids`"):
        lmi_settings(ur5, s, "lmi", None, "pullback", "auto", "spheres", True)
