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
