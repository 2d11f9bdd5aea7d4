"""Real KUKA LWR4+ logs (FloBaRoID): OLS vs the CAD URDF on held-out runs. Skips without the data."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless import CADModel, identify, read_trajectory

from conftest import KUKA, realdata

pytestmark = pytest.mark.realdata
TERMS = ("fv", "fc", "offset")


@pytest.fixture(scope="module")
def logs(kuka):
    return [read_trajectory(realdata(KUKA / "data" / "KUKA" / "HW" / f"measurements_{i}.npz"), robot=kuka) for i in (1, 2, 3)]


def test_ols_beats_cad_on_repeat_run_every_joint(kuka, logs):
    res = identify(kuka, logs[0], joint_terms=TERMS)
    ols, cad = res.score(logs[1]), CADModel(kuka).fit().score(logs[1])
    assert np.all(ols.nrmse < cad.nrmse), (ols.nrmse, cad.nrmse)
    # repeatability: the same trajectory run again is predicted almost as well as the training run
    assert np.all(ols.nrmse < 1.5 * res.train_metrics.nrmse + 0.01)


def test_kuka_log_is_read_with_joint_names_and_rate(kuka, logs):
    assert logs[0].joint_names == kuka.joint_names
    assert len(logs[0]) == 5027
    assert 190 < logs[0].rate < 210


@pytest.mark.parametrize("train, test, limit, every_joint_beats_ols", [(1, 3, 0.16, True), (3, 1, 0.13, False)])
def test_cli_defaults_generalise_to_another_trajectory(tmp_path, train, test, limit, every_joint_beats_ols):
    """The README's cross-trajectory check: `sensorless identify` with its defaults (LMI, γ by
    cross-validation, CAD prior) trained on one excitation predicts the other better than the
    CAD URDF on every joint and better than unconstrained OLS on average (measured: 1→3 13.6 %
    vs CAD 31.0 % and OLS 39.8 %; 3→1 10.8 % vs 28.4 % and 11.5 %; mean NRMSE of the range)."""
    import json

    from typer.testing import CliRunner

    from sensorless.cli import app

    hw = KUKA / "data" / "KUKA" / "HW"
    out = tmp_path / "model"
    r = CliRunner().invoke(app, ["identify", "--robot", str(realdata(KUKA / "model" / "kuka_lwr4.urdf")),
                                 "--data", str(realdata(hw / f"measurements_{train}.npz")),
                                 "--validate", str(hw / f"measurements_{test}.npz"), "--out", str(out), "--no-plot"])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "result.json").read_text())
    assert doc["method"] == "lmi" and doc["diagnostics"]["lmi"]["consistent"]
    val = next(iter(doc["validation"].values()))
    per = {m: np.array([v["nrmse"] for v in val[m]["per_joint"].values()]) for m in ("lmi", "ols", "cad")}
    assert per["lmi"].mean() < limit and per["lmi"].mean() < per["ols"].mean()
    assert np.all(per["lmi"] < per["cad"]), per
    if every_joint_beats_ols:
        assert np.all(per["lmi"] < per["ols"]), per
