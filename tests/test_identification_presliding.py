"""The presliding joint term of a rigid-body model (identification.presliding, regressor.terms): a simulated
two-link arm whose joint j1 has LuGre friction (presliding, hysteresis) and j2 a static law."""

import os

import numpy as np
import pinocchio as pin
import pytest

from sensorless.data.trajectory import Trajectory
from sensorless.estimation.momentum import MomentumDynamics, MomentumObserver
from sensorless.identification import identify
from sensorless.identification.artifact import load_model_folder, save_model_folder
from sensorless.identification.friction_model import reversal_mask
from sensorless.regressor.terms import ModelStructure
from sensorless.robot import load_robot
from sensorless_studies.simulation.lugre import LuGreJoint, lugre_friction, velocity_profile

TWO_LINK = os.path.join(os.path.dirname(__file__), "data", "two_link.urdf")
LUGRE = LuGreJoint(fc=1.0, fs=1.4, vs=0.02, sigma0=300.0, sigma1=1.0, sigma2=0.3)
STATIC = LuGreJoint(fc=0.6, fs=0.6, vs=0.02, sigma0=None, sigma2=0.2)
TERMS = "fv,fc,offset,presliding"


def arm_log(seed: int, duration: float = 40.0, rate: float = 200.0) -> Trajectory:
    robot = load_robot(TWO_LINK)
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration * rate)) / rate
    profs = [velocity_profile(duration, seed * 10 + k, v_max=0.4) for k in range(2)]
    qva = [p(t) for p in profs]
    q = np.column_stack([x[0] for x in qva]) * 0.5
    v = np.column_stack([x[1] for x in qva]) * 0.5
    a = np.column_stack([x[2] for x in qva]) * 0.5
    q = np.clip(q, -1.5, 1.5)
    profs = [type(p)(p.t, p.v * 0.5) for p in profs]
    tau_f = np.column_stack([lugre_friction(law, p, t)[0] for law, p in zip((LUGRE, STATIC), profs)])
    m, d = robot.model, robot.model.createData()
    rigid = np.array([pin.rnea(m, d, q[i], v[i], a[i]) for i in range(len(t))])
    tau = rigid + tau_f + rng.normal(0, 0.01, tau_f.shape)
    return Trajectory(t=t, q=q + rng.normal(0, 1e-5, q.shape), v=v + rng.normal(0, 2e-4, v.shape), a=a, tau=tau,
                      joint_names=("j1", "j2"), source=f"<arm seed {seed}>")


@pytest.fixture(scope="module")
def fits():
    robot = load_robot(TWO_LINK)
    train, test = [arm_log(0), arm_log(1)], arm_log(5, 30.0)
    state = identify(ModelStructure(robot, joint_terms=TERMS, coulomb_smoothing=1e-3), train)
    static = identify(ModelStructure(robot, joint_terms="fv,fc,offset", coulomb_smoothing=1e-3), train)
    return state, static, test


def test_lugre_joint_keeps_presliding_and_halves_the_error_near_reversals(fits):
    state, static, test = fits
    rec = state.diagnostics["presliding_search"]
    assert rec["j1"]["kept"] and not rec["j2"]["kept"]  # the static joint keeps its static law (BIC)
    assert state.structure.terms_of("j1")[-1] == "presliding" and "presliding" not in state.structure.terms_of("j2")
    assert 0.3 * LUGRE.fc / LUGRE.sigma0 < rec["j1"]["presliding_distance"] < 3 * LUGRE.fc / LUGRE.sigma0
    near = reversal_mask(test.t, test.v[:, 0])
    err = [np.sqrt(np.mean((r.predict(test)[near, 0] - test.tau[near, 0]) ** 2)) for r in (state, static)]
    assert err[0] <= 0.5 * err[1], err


def test_regressor_times_parameters_is_the_prediction_and_the_state_carries_over_chunks(fits):
    state, _, test = fits
    s = state.structure
    W = s.regressor(test)
    pred = s.torques(state.parameters, test, chunk=97)  # chunks must carry the state
    np.testing.assert_allclose(W @ state.parameters, pred, atol=1e-9)
    # the column is the friction state of friction_state along the log from 0
    from sensorless.regressor.friction_state import dahl_states, play
    p = s.presliding["j1"]
    col = W[:, 0, s.joint_term_index("j1", "presliding")]
    np.testing.assert_allclose(col, dahl_states(play(test.q[:, 0], p["play"]), test.v[:, 0], [p["k"]])[:, 0, 0])


def test_model_folder_round_trip_predict_and_observer(fits, tmp_path):
    state, _, test = fits
    save_model_folder(tmp_path, state)
    art = load_model_folder(tmp_path / "result.json", load_robot(TWO_LINK))
    assert art.structure.presliding == state.structure.presliding
    np.testing.assert_allclose(art.structure.torques(art.parameters, test), state.predict(test), atol=1e-9)
    dyn = MomentumDynamics(art.structure, art.parameters)
    short = test.take(slice(0, 600))
    run = MomentumObserver(dyn, gain=30.0).run(short)
    obs = MomentumObserver(dyn, gain=30.0, dt=float(short.t[1] - short.t[0]))
    step = np.array([obs.step(short.q[i], short.v[i], short.tau[i]) for i in range(len(short))])
    np.testing.assert_allclose(step, run.r, atol=1e-8)
    # without the state the observer would see the presliding friction as an external torque
    assert np.sqrt(np.mean(run.r[:, 0] ** 2)) < 0.1


def test_default_terms_unchanged_and_state_needs_whole_logs():
    s = ModelStructure(load_robot(TWO_LINK))
    assert "presliding" not in s.joint_terms and s.friction_states(arm_log(3, 2.0)) is None
    sp = ModelStructure(load_robot(TWO_LINK), joint_terms="fv,presliding", presliding={"j1": {"k": 100.0, "play": 0.0},
                                                                                        "j2": {"k": 50.0}})
    with pytest.raises(Exception, match="history of q"):
        sp.joint_features(np.zeros((3, 2)), np.zeros((3, 2)))


def _csv(traj: Trajectory, path) -> str:
    cols = {"t": traj.t}
    for k, j in enumerate(traj.joint_names):
        cols.update({f"pos_{j}": traj.q[:, k], f"vel_{j}": traj.v[:, k], f"tau_{j}": traj.tau[:, k]})
    np.savetxt(path, np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols), comments="")
    return str(path)


def test_cli_identify_predict_with_presliding(tmp_path):
    import json

    from typer.testing import CliRunner

    from sensorless.cli import app

    runner = CliRunner()
    train, test = _csv(arm_log(0), tmp_path / "train.csv"), _csv(arm_log(5, 20.0), tmp_path / "test.csv")
    cols = ["--columns", "q=pos_{joint};v=vel_{joint};tau=tau_{joint}"]
    r = runner.invoke(app, ["identify", "--robot", TWO_LINK, "--data", train, *cols, "--no-plot",
                            "--joint-terms", "fv,fc,stribeck,offset,presliding", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "m" / "result.json").read_text())
    assert set(doc["settings"]["presliding"]) == {"j1"}
    assert doc["diagnostics"]["presliding_search"]["j2"]["kept"] is False
    r = runner.invoke(app, ["predict", "--robot", TWO_LINK, "--model", str(tmp_path / "m"), "--data", test,
                            "--out", str(tmp_path / "pred.npz")])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["identify", "--robot", TWO_LINK, "--data", train, *cols, "--scheduler", "local",
                            "--joint-terms", "fv,presliding", "--out", str(tmp_path / "m2")])
    assert r.exit_code != 0 and "--scheduler" in r.output
