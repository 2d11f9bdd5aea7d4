"""Payload determinacy (issue 23, item 4): at a frame whose origin the log does not move only
m·c is determined (refused without --com, within 3 % with it); a mass at its bound 0 is never
an estimate; a joint the consistency check flags is left out of the headline."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from test_cli_psm import COLS, _run
from sensorless_studies.simulation.psm_logs import psm_motion, psm_truth
from test_identification_payload import _psm_payload_torques

from sensorless.errors import ExcitationError
from sensorless_studies.experiments.psm_identification import write_psm_csv
from sensorless.identification import identify
from sensorless.identification.payload import identify_payload

M, COM = 0.2, np.array([0.01, 0.0, 0.05])


@pytest.fixture(scope="module")
def case():
    rng = np.random.default_rng(7)
    s, p = psm_truth(rng)
    free = psm_motion(1, 15.0)
    free = free.with_(tau=s.evaluate(free.q, free.v, free.a) @ p + rng.normal(size=(len(free), 7)) * 0.01)
    return s, p, identify(s, free)


def _log(s, p, frame, m=M, com=COM, seed=5, scale_q2=0.0):
    mot = psm_motion(seed, 20.0)
    tau_p = _psm_payload_torques(s, mot, frame, pin.Inertia(m, np.asarray(com), np.zeros((3, 3))))
    tau_p[:, 1] *= 1.0 + scale_q2
    return mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p + tau_p
                     + np.random.default_rng(seed + 1).normal(size=(len(mot), 7)) * 0.01)


def test_fixed_origin_frame_refuses_mass_without_com_and_recovers_it_with_com(case):
    """'rcm' is the remote centre of motion: its origin never moves, so m·g has no lever and
    only m·c reaches the joints (the fit gave m = 1e12 kg here before)."""
    s, p, result = case
    log = _log(s, p, "rcm")
    for mode in ("auto", "com", "full"):
        with pytest.raises(ExcitationError, match="`com=X,Y,Z`") as exc:
            identify_payload(result, log, "rcm", mode=mode, n_boot=0)
        assert "origin does not move" in str(exc.value) and "'rcm'" in str(exc.value)
    est = identify_payload(result, log, "rcm", com=COM, n_boot=20)
    assert abs(est.mass - M) / M < 0.03, est
    assert est.determinacy["mass"] == "from the given CoM" and est.determinacy["first_moment"] == "data"
    assert est.determinacy["mass_lever_m"] < 1e-9
    doc = est.to_dict()
    assert doc["determinacy"]["mass"] == "from the given CoM"
    # a CoM at the frame origin carries no mass through m·c
    with pytest.raises(ExcitationError, match="carries no mass"):
        identify_payload(result, log, "rcm", com=np.zeros(3), n_boot=0)
    # a frame whose origin moves: the log determines m itself
    moving = identify_payload(result, _log(s, p, "pitch_end"), "pitch_end", mode="com", n_boot=0)
    assert moving.determinacy["mass"] == "data" and moving.determinacy["mass_lever_m"] > 0.1
    assert abs(moving.mass - M) / M < 0.03


def test_mass_at_its_bound_is_labelled_not_determined(case):
    s, p, result = case
    log = _log(s, p, "pitch_end", m=0.0)
    est = identify_payload(result, log, "pitch_end", mode="com", n_boot=20)
    assert est.mass == 0.0 and est.mass_at_bound
    assert est.determinacy["mass"] == "at bound: not determined"
    assert "not determined" in str(est) and est.to_dict()["determinacy"]["mass"] == "at bound: not determined"
    # a real payload is not at the bound
    assert not identify_payload(result, _log(s, p, "pitch_end"), "pitch_end", mode="com", n_boot=0).mass_at_bound


def test_flagged_joint_is_not_in_the_headline(case):
    """q2 sees 60 % (or 120 %) more payload torque (a wrong gain): it is flagged and the headline
    does not depend on its torque at all, while the all-joint fit does."""
    s, p, result = case
    ests = [identify_payload(result, _log(s, p, "tool_tip", com=np.zeros(3), seed=9, scale_q2=k), "tool_tip",
                             mode="com", n_boot=0) for k in (0.6, 1.2)]
    for est in ests:
        assert est.flagged_joints == ["q2"] and est.headline_excludes == ["q2"]
        assert abs(est.mass - M) / M < 0.03, est
        assert est.to_dict()["headline_excludes"] == ["q2"]
    with_q2 = [e.diagnostics["mass_with_flagged"] for e in ests]
    assert abs(with_q2[0] - with_q2[1]) > 1e-5  # the test is not vacuous: q2 moves the all-joint fit
    assert ests[0].mass == pytest.approx(ests[1].mass, abs=1e-9)


@pytest.fixture(scope="module")
def psm_cli(tmp_path_factory, case):
    """A PSM model folder from `sensorless identify` and payload logs (CSV, 200 Hz)."""
    d = tmp_path_factory.mktemp("det")
    s, p, _ = case
    rng = np.random.default_rng(3)
    mot = psm_motion(1, 15.0, rate=200.0)
    write_psm_csv(mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p + rng.normal(size=(len(mot), 7)) * 0.003),
                  d / "train.csv")
    code, out = _run(["identify", "--robot", "dvrk_psm", "--data", d / "train.csv", *COLS, "--out", d / "model"])
    assert code == 0, out
    for name, frame, m in (("rcm.csv", "rcm", M), ("none.csv", "pitch_end", 0.0)):
        mot = psm_motion(5, 15.0, rate=200.0)
        tau = (s.evaluate(mot.q, mot.v, mot.a) @ p + rng.normal(size=(len(mot), 7)) * 0.003
               + _psm_payload_torques(s, mot, frame, pin.Inertia(m, COM, np.zeros((3, 3)))))
        write_psm_csv(mot.with_(tau=tau), d / name)
    return d


def test_cli_payload_at_a_fixed_origin_names_com(psm_cli):
    d = psm_cli
    base = ["payload", "--robot", "dvrk_psm", "--model", d / "model", *COLS, "--n-boot", "0"]
    code, out = _run(base + ["--data", d / "rcm.csv", "--frame", "rcm", "--out", d / "a.json"])
    assert code == 2 and "--com" in out and not (d / "a.json").exists(), out
    code, out = _run(base + ["--data", d / "rcm.csv", "--frame", "rcm", "--com", "0.01,0,0.05", "--out", d / "b.json"])
    assert code == 0, out
    doc = json.loads((d / "b.json").read_text())
    assert abs(doc["mass"] - M) / M < 0.03 and doc["determinacy"]["mass"] == "from the given CoM"
    assert "determined by the log" in out


def test_cli_mass_at_bound_refused_unless_accepted(psm_cli):
    d = psm_cli
    base = ["payload", "--robot", "dvrk_psm", "--model", d / "model", *COLS, "--n-boot", "0", "--mode", "com",
            "--data", d / "none.csv", "--frame", "pitch_end"]
    code, out = _run(base + ["--out", d / "c.json"])
    assert code == 2 and "bound" in out and "--accept-bound" in out and not (d / "c.json").exists(), out
    code, out = _run(base + ["--accept-bound", "--out", d / "c.json"])
    assert code == 0, out
    assert json.loads((d / "c.json").read_text())["determinacy"]["mass"] == "at bound: not determined"
    assert "at its bound 0: not determined" in out
