"""The dVRK PSM through every command (issue 11): identify / predict / estimate-force / payload /
psm-identify with `--robot dvrk_psm` on header-less CSV logs, plus the real-data held-out check
and the payload acceptance (100 g and 200 g on the real excitation trajectory)."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from conftest import REALDATA, realdata
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless_studies.experiments.psm_identification import paired_payload_logs, write_psm_csv
from sensorless_studies.simulation.psm_logs import psm_motion, psm_truth, tip_force_efforts

COLS = ["--columns", "q=0:7;v=7:14;tau=14:21", "--rate", "200"]
NOISE = 0.003
WPI = REALDATA / "dvrk_psm_wpi" / "data" / "psm" / "measured_trajectory"


def _run(args):
    r = CliRunner().invoke(app, [str(a) for a in args])
    return r.exit_code, r.output


@pytest.fixture(scope="module")
def psm_files(tmp_path_factory):
    """A simulated PSM (physically consistent truth) and header-less CSV logs at 200 Hz."""
    d = tmp_path_factory.mktemp("psm")
    rng = np.random.default_rng(21)
    s, p = psm_truth(rng)
    noise = NOISE

    def log(seed, duration):
        mot = psm_motion(seed, duration, rate=200.0)
        return mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p + rng.normal(size=(len(mot), 7)) * noise)

    train, test = log(1, 15.0), log(2, 5.0)
    write_psm_csv(train, d / "train.csv")
    write_psm_csv(test, d / "test.csv")
    code, out = _run(["identify", "--robot", "dvrk_psm", "--data", d / "train.csv", "--validate", d / "test.csv",
                      *COLS, "--out", d / "model"])
    assert code == 0, out
    return d, s, p


def test_identify_with_robot_dvrk_psm_saves_a_loadable_model(psm_files):
    """Regression: identify rejected --robot dvrk_psm ("neither a .urdf/.xml file nor an
    example-robot-data name")."""
    d, s, _ = psm_files
    doc = json.loads((d / "model" / "result.json").read_text())
    assert doc["settings"]["structure"] == "transmission" and doc["robot"]["coordinates"] == list(s.coordinates)
    assert (d / "model" / "drive_terms.json").exists() and doc["urdf"] is None and "coupled" in doc["urdf_error"]
    val = doc["validation"][str(d / "test.csv")]["ols"]
    assert max(v["rmse"] for v in val["per_joint"].values()) < 2 * NOISE, val  # the noise floor
    code, out = _run(["predict", "--robot", "dvrk_psm", "--model", d / "model", "--data", d / "test.csv", *COLS,
                      "--out", d / "pred.npz"])
    assert code == 0, out
    z = np.load(d / "pred.npz")
    assert z["tau_pred"].shape == (1000, 7) and list(z["joints"]) == list(s.coordinates)
    err = np.sqrt(((z["tau_pred"] - z["tau_measured"]) ** 2).mean(0))
    assert np.all(err < 3 * NOISE), err


def test_lmi_identify_on_the_psm_with_cli_defaults(psm_files):
    d, _, _ = psm_files
    code, out = _run(["identify", "--robot", "dvrk_psm", "--data", d / "train.csv", *COLS, "--method", "lmi",
                      "--gamma", "1e-3", "--out", d / "lmi"])
    assert code == 0, out
    doc = json.loads((d / "lmi" / "result.json").read_text())
    assert doc["diagnostics"]["lmi"]["consistent"] and "no inertial prior" in doc["diagnostics"]["prior_note"]


def test_estimate_force_on_the_psm_tool_tip(psm_files):
    """Regression: estimate-force rejected --robot dvrk_psm; the estimator had no frame_id."""
    d, s, p = psm_files
    mot = psm_motion(5, 4.0, rate=200.0)
    F = np.stack([np.sin(mot.t), 0.5 * np.cos(2 * mot.t), -1.0 + 0 * mot.t], axis=1)
    write_psm_csv(mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p + tip_force_efforts(s, mot, F)), d / "push.csv")
    code, out = _run(["estimate-force", "--robot", "dvrk_psm", "--model", d / "model", "--data", d / "push.csv",
                      *COLS, "--frame", "tool_tip", "--out", d / "force.npz"])
    assert code == 0, out
    z = np.load(d / "force.npz")
    err = np.sqrt(((z["force"] - F)[100:-100] ** 2).mean(0))  # ends: derivative edge effects
    assert np.all(err < 0.1), err


def test_payload_command_on_the_psm_with_a_paired_no_load_log(psm_files):
    d, s, p = psm_files
    m = 0.15
    nl, ld = paired_payload_logs(s, p, psm_motion(7, 15.0, rate=200.0), pin.Inertia(m, np.array([0.0, 0.0, 0.3]), np.zeros((3, 3))),
                                 "pitch_end", noise_std=np.full(7, 0.003), seed=3)
    write_psm_csv(nl, d / "noload.csv")
    write_psm_csv(ld, d / "load.csv")
    code, out = _run(["payload", "--robot", "dvrk_psm", "--model", d / "model", "--data", d / "load.csv",
                      "--no-load", d / "noload.csv", *COLS, "--frame", "pitch_end", "--mode", "com", "--n-boot", "20",
                      "--out", d / "payload.json"])
    assert code == 0, out
    doc = json.loads((d / "payload.json").read_text())
    assert abs(doc["mass"] - m) / m < 0.03, doc["mass"]
    assert doc["weight_N"] == pytest.approx(doc["mass"] * 9.81) and doc["mass_std"] > 0
    assert [c["joint"] for c in doc["per_joint"]] == list(s.coordinates) and doc["flagged_joints"] == []
    assert "q3" not in doc["settings"]["offsets"]  # auto: no offset where it would absorb m·g
    assert "per-joint consistency" in out
    # a failed run (unknown frame) leaves no output and names the known frames
    code, out = _run(["payload", "--robot", "dvrk_psm", "--model", d / "model", "--data", d / "load.csv", *COLS,
                      "--frame", "nope", "--out", d / "bad.json"])
    assert code == 2 and "unknown frame 'nope'" in out and "tool_tip" in out and not (d / "bad.json").exists()
    code, out = _run(["payload", "--robot", "dvrk_psm", "--model", d / "model", "--data", d / "load.csv",
                      "--no-load", d / "noload.csv", "--no-load", d / "noload.csv", *COLS, "--frame", "pitch_end",
                      "--out", d / "bad.json"])
    assert code == 2 and "pair them" in out and not (d / "bad.json").exists()


def test_psm_identify_takes_train_and_test_files_and_saves_a_model(psm_files, tmp_path):
    """Regression: `experiment psm-identify` accepted only the WPI folder layout and saved no model."""
    d, s, _ = psm_files
    code, out = _run(["experiment", "psm-identify", "--train", d / "train.csv", "--test", d / "test.csv",
                      "--smoothing", "0.05", "--out", tmp_path / "psm"])
    assert code == 0, out
    rep = json.loads((tmp_path / "psm" / "psm_identification.json").read_text())
    assert "published" not in rep and set(rep["identified"]) == {"ols", "wls"}
    doc = json.loads((tmp_path / "psm" / "result.json").read_text())
    assert doc["settings"]["preprocessing"]["lowpass"] == 5.4 and doc["settings"]["coulomb_smoothing"] == 0.05
    from sensorless.identification.artifact import SCHEMA_VERSION, load_model_folder
    from sensorless.robots.dvrk_psm import psm_robot

    assert doc["schema_version"] == SCHEMA_VERSION  # and the one validator accepts it:
    assert load_model_folder(tmp_path / "psm", psm_robot()).parameters.size == len(doc["parameters"])
    code, out = _run(["predict", "--robot", "dvrk_psm", "--model", tmp_path / "psm", "--data", d / "test.csv", *COLS,
                      "--out", tmp_path / "pred.npz"])
    assert code == 0, out
    code, out = _run(["experiment", "psm-identify", "--train", d / "train.csv", "--out", tmp_path / "x"])
    assert code == 2 and "--test" in out and not (tmp_path / "x").exists()


def test_psm_identify_lmi_saves_the_lmi_model_and_warns_once_per_cause(psm_files, tmp_path):
    """`--lmi` keeps the physically consistent model in result.json (it saved the OLS one), and a
    warning repeated by the fits is printed once (issue 42)."""
    d, s, _ = psm_files
    code, out = _run(["experiment", "psm-identify", "--train", d / "train.csv", "--test", d / "test.csv",
                      "--smoothing", "0.05", "--lmi", "--out", tmp_path / "psm"])
    assert code == 0, out
    assert json.loads((tmp_path / "psm" / "result.json").read_text())["method"] == "lmi"
    assert "result.json: the LMI model" in " ".join(out.split())
    lines = [" ".join(w.split()) for w in out.split("warning:")[1:]]
    assert len(lines) == len(set(lines)), lines


def test_psm_model_and_urdf_model_are_not_mixed(psm_files, tmp_path):
    d, _, _ = psm_files
    code, out = _run(["predict", "--robot", "panda", "--model", d / "model", "--data", d / "test.csv", *COLS,
                      "--out", tmp_path / "p.npz"])
    assert code == 2 and "dvrk_psm" in out and not (tmp_path / "p.npz").exists()
    code, out = _run(["identify", "--robot", "dvrk_psm", "--data", d / "train.csv", *COLS, "--joint-terms", "fv",
                      "--out", tmp_path / "m"])
    assert code == 2 and "drive set" in out and not (tmp_path / "m").exists()


# ---- real WPI logs ----------------------------------------------------------------------------------
@pytest.mark.realdata
def test_real_psm_identify_then_predict_through_the_cli(tmp_path):
    root = realdata(WPI)
    code, out = _run(["identify", "--robot", "dvrk_psm", "--data", root / "one_results.csv", "--validate",
                      root / "two_results.csv", *COLS, "--lowpass", "5.4", "--coulomb-smoothing", "0.2",
                      "--out", tmp_path / "m"])
    assert code == 0, out
    doc = json.loads((tmp_path / "m" / "result.json").read_text())
    per = doc["validation"][str(root / "two_results.csv")]["ols"]["per_joint"]
    nrmse = np.array([per[c]["nrmse"] for c in ("q1", "q2", "q3", "q4", "m5", "m6", "m7")])
    assert np.all(nrmse[:3] < 0.07) and np.all(nrmse < 0.13), nrmse


@pytest.mark.realdata
@pytest.mark.parametrize("mass", [0.1, 0.2])
def test_payload_acceptance_on_the_real_psm_trajectory(tmp_path, mass):
    """Acceptance (issue 11): a point mass on the instrument link, efforts simulated on the real
    excitation trajectory (one_results) by the model identified on it, AR(1) noise at its residual
    level, the 0.075 N·m τ2 session offset; the robot model given to `payload` is identified on a
    different log (two_results). The command recovers m·g within 10 % from the paired no-load log."""
    from sensorless.identification import identify
    from sensorless.robots import psm_structure, read_psm_log

    root = realdata(WPI)
    s = psm_structure(coulomb_smoothing=0.2)
    one = read_psm_log(root / "one_results.csv")
    truth = identify(s, one)
    sigma = np.array(list(truth.diagnostics["residual_sigma"].values()))
    nl, ld = paired_payload_logs(s, truth.parameters, one, pin.Inertia(mass, np.array([0.0, 0.0, 0.35]), np.zeros((3, 3))),
                                 "pitch_end", noise_std=sigma, seed=1)
    write_psm_csv(nl, tmp_path / "noload.csv")
    write_psm_csv(ld, tmp_path / "load.csv")
    code, out = _run(["identify", "--robot", "dvrk_psm", "--data", root / "two_results.csv", *COLS, "--lowpass", "5.4",
                      "--coulomb-smoothing", "0.2", "--out", tmp_path / "m"])
    assert code == 0, out
    code, out = _run(["payload", "--robot", "dvrk_psm", "--model", tmp_path / "m", "--data", tmp_path / "load.csv",
                      "--no-load", tmp_path / "noload.csv", *COLS, "--lowpass", "5.4", "--frame", "pitch_end",
                      "--n-boot", "50", "--out", tmp_path / "payload.json"])
    assert code == 0, out
    doc = json.loads((tmp_path / "payload.json").read_text())
    assert abs(doc["weight_N"] - mass * 9.81) / (mass * 9.81) < 0.10, doc["weight_N"]
    assert abs(doc["mass"] - mass) < 3 * doc["mass_std"] + 0.02 * mass


def test_every_psm_name_loads_the_psm_in_every_command(tmp_path):
    """excite, identify, predict, estimate-force and payload share one loader: the names excite
    accepted are the names every command accepts (regression: only excite knew them)."""
    from sensorless.cli.common import load_robot_arg
    from sensorless.robots import COORDINATES
    from sensorless.robots.registry import find_robot

    for name in find_robot("dvrk_psm").names + ("DVRK_PSM",):
        assert load_robot_arg(name, None, None).joint_names == COORDINATES
    code, out = _run(["excite", "--robot", "dvrk_psm", "--harmonics", "1", "--n-samples", "20", "--maxiter", "1",
                      "--base-freq", "0.2", "--out", tmp_path / "exc"])
    assert code == 0, out
    code, out = _run(["identify", "--robot", "dvrk_psm", "--lock", "q1", "--data", tmp_path / "none.csv",
                      "--out", tmp_path / "m"])
    assert code == 2 and "--lock" in out and "neither a .urdf" not in out
