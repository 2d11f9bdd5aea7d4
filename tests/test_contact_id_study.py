"""The legged-robot study in a reduced form: what the published comparison claims.

With the simulator's exact accelerations the physical models are limited only by noise and
soft contact; with accelerations estimated from 100 Hz velocities (what a user has) the
acceleration error dominates every physical model — both are exercised here.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from sensorless.experiments.contact_id import ContactStudyConfig, run

EPISODES = (("wobble", {}), ("crawl", {}), ("trot", {"speed": 0.1}), ("trot", {"speed": 0.2}), ("trot", {"speed": 0.3}))


def _config(acceleration):
    return ContactStudyConfig(
        quick=True, acceleration=acceleration, train_sizes=(100, 2000), train_episodes=EPISODES,
        episode_duration=5.0, eval_duration=5.0, validation=ContactStudyConfig.validation[:3],
        mlp_hidden=(128, 128), mlp_epochs=25,
    )


@pytest.fixture(scope="module")
def exact(tmp_path_factory):
    return run(tmp_path_factory.mktemp("cid"), config=_config("simulator"))


def test_outputs_written(exact, tmp_path_factory):
    assert exact["rows"] and {"LMI", "SVD", "MLP"} <= exact["rows"][0]["rmse"].keys()
    assert exact["soft_contact_residual"]["relative"] < 0.02  # soft contact: < 2 % of ‖Sᵀτ‖


def test_lmi_generalises_and_recovers_mass(exact):
    c = exact["checks"]
    small, big = exact["rows"]
    assert all(r["lmi_consistent"] for r in exact["rows"])
    assert c["lmi_beats_mlp_smallest_set"] and c["lmi_beats_mlp_ood_every_size"]
    assert c["jump_lmi_over_mlp_largest"] <= 0.5
    assert c["total_mass_error_largest"] < 0.02
    # LMI is as good as the true parameters on held-out data (the achievable floor) ...
    assert c["validation_lmi_over_true_parameters_largest"] < 1.05
    # ... and on little data it beats the unconstrained projected regression everywhere
    assert all(small["rmse"]["LMI"][g] < small["rmse"]["SVD"][g] for g in ("validation", "ood_trot", "ood_jump"))


def test_realistic_accelerations_keep_lmi_ahead_out_of_distribution(tmp_path):
    res = run(tmp_path, config=_config("savgol"))
    small = res["rows"][0]
    assert small["rmse"]["LMI"]["ood_trot"] < small["rmse"]["SVD"]["ood_trot"]
    assert small["rmse"]["LMI"]["validation"] < small["rmse"]["MLP"]["validation"]
    assert np.isfinite(res["noise_floor_rmse"]["validation"])
    json.dumps(res)  # serialisable
