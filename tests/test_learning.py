"""Learned torque models: causal window features, deterministic training, safe save/load,
and a hybrid model that learns a known synthetic residual (tiny settings, CPU)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import torch

from sensorless.data.trajectory import Trajectory
from sensorless.errors import DataError, SensorlessError
from sensorless.torque_models import PhysicalModel
from sensorless.excitation import random_fourier
from sensorless.learning import (
    HybridModel,
    LearnedTorqueModel,
    MLPTorqueModel,
    TrainConfig,
    WindowFeatures,
    load_network,
    sliding_window,
)
from sensorless.regressor import ModelStructure
from sensorless.testing import perturbed_truth, synthetic_trajectory

TINY = dict(epochs=30, patience=8, batch_size=128, lr=3e-3)


# ---- features ---------------------------------------------------------------------
def test_sliding_window_shape_content_and_causality():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(50, 3))
    W, s = 4, 2
    X = sliding_window(x, W, s)
    assert X.shape == (50, W * 3)
    i = 30
    np.testing.assert_array_equal(X[i], np.concatenate([x[i - 6], x[i - 4], x[i - 2], x[i]]))
    # early rows repeat the first sample as history
    np.testing.assert_array_equal(X[1], np.concatenate([x[0], x[0], x[0], x[1]]))
    # causal: changing the future leaves every earlier row unchanged
    y = x.copy()
    y[i + 1 :] += 100.0
    np.testing.assert_array_equal(sliding_window(y, W, s)[: i + 1], X[: i + 1])
    assert not np.allclose(sliding_window(y, W, s)[i + 1], X[i + 1])
    with pytest.raises(DataError):
        sliding_window(x, 0)


def test_window_features_with_model_torque_and_normalisation():
    rng = np.random.default_rng(1)
    N, n = 40, 3
    traj = Trajectory(t=np.arange(N) * 0.01, q=rng.normal(size=(N, n)), v=rng.normal(size=(N, n)), joint_names=("a", "b", "c"))
    tau = rng.normal(size=(N, n))
    f = WindowFeatures(window=5)
    Z = f.fit_transform([traj], [tau])
    assert Z.shape == (N, 5 * 2 * n + n)
    np.testing.assert_allclose(Z.mean(0), 0, atol=1e-12)
    # stored statistics survive a JSON round trip; joints are matched by name
    g = WindowFeatures.from_dict(f.to_dict())
    swapped = traj.select_joints(["c", "a", "b"])
    np.testing.assert_allclose(g.transform(swapped, tau), Z)
    with pytest.raises(DataError, match="lacks joint"):
        g.transform(traj.select_joints(["a", "b"]), tau)


# ---- a small synthetic problem ---------------------------------------------------
def _residual(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A setup-specific effect the rigid-body model cannot explain (friction-like, pose-dependent)."""
    r = np.zeros_like(q)
    r[:, 0] = 1.5 * np.tanh(v[:, 0] / 0.1) * (1 + 0.5 * np.cos(q[:, 1]))
    r[:, 1] = 2.0 * np.sin(q[:, 0]) + 0.5 * v[:, 1]
    r[:, 3] = -1.0 * np.tanh(v[:, 3] / 0.2)
    return r


@pytest.fixture(scope="module")
def synthetic(panda):
    truth = perturbed_truth(panda, rng=0)

    def log(seed, dur, resid=True):
        tr = synthetic_trajectory(truth, random_fourier(panda, rng=seed, base_freq=0.2).sample(100, dur), noise_std=0.05, rng=seed + 100)
        return tr.with_(tau=tr.tau + _residual(tr.q, tr.v)) if resid else tr

    phys = PhysicalModel(panda).fit(log(1, 20.0, resid=False))
    # many short, different excitation loops cover the joint space; the test loop is new
    return phys, [log(s, 5.0) for s in range(2, 26)], log(99, 5.0)


def test_hybrid_model_learns_the_residual(synthetic):
    phys, train, test = synthetic
    hy = HybridModel(phys, window=3, stride=2, hidden=(64, 64), per_joint=True, seed=0, **TINY).fit(train)
    before = phys.score(test).rmse
    after = hy.score(test).rmse
    hit = [0, 1, 3]
    assert np.all(after[hit] < 0.4 * before[hit]), (before, after)
    assert np.mean(after) < 0.5 * np.mean(before)
    np.testing.assert_allclose(hy.predict(test), phys.predict(test) + hy.predict_residual(test))
    assert hy.history_["epochs_run"] <= TINY["epochs"] and hy.history_["n_val"] > 0


def _weights(model):
    return {k: v.clone() for k, v in model.net_.state_dict().items()}


def test_training_is_deterministic_for_a_seed(synthetic):
    phys, train, _ = synthetic
    kw = dict(window=2, hidden=(32, 32), seed=7, epochs=5, patience=5, batch_size=64)
    a, b = HybridModel(phys, **kw).fit(train), HybridModel(phys, **kw).fit(train)
    wa, wb = _weights(a), _weights(b)
    assert wa.keys() == wb.keys() and all(torch.equal(wa[k], wb[k]) for k in wa)
    c = HybridModel(phys, **{**kw, "seed": 8}).fit(train)
    assert not all(torch.equal(wa[k], v) for k, v in _weights(c).items())


def test_save_load_round_trip_weights_only(synthetic, tmp_path, panda):
    phys, train, test = synthetic
    hy = HybridModel(phys, window=2, hidden=(16,), seed=0, epochs=3, patience=3).fit(train)
    hy.save(tmp_path / "res")
    assert {p.name for p in (tmp_path / "res").iterdir()} == {"weights.pt", "model.json"}
    back = HybridModel.load(tmp_path / "res", phys)
    np.testing.assert_array_equal(back.predict(test), hy.predict(test))
    # the physical model can also come from saved parameters
    fixed = PhysicalModel.from_parameters(phys.structure_, phys.parameters_)
    np.testing.assert_allclose(HybridModel.load(tmp_path / "res", fixed).predict(test), hy.predict(test))
    lt = LearnedTorqueModel(panda, window=2, hidden=(16,), seed=0, epochs=2).fit(train)
    lt.save(tmp_path / "lt")
    np.testing.assert_array_equal(LearnedTorqueModel.load(tmp_path / "lt", panda).predict(test), lt.predict(test))
    with pytest.raises(DataError, match="not a HybridModel"):
        HybridModel.load(tmp_path / "lt", phys)


class _Evil:
    def __reduce__(self):
        import os

        return (os.system, ("echo pwned > /dev/null",))


def test_loading_refuses_pickled_code(synthetic, tmp_path):
    phys, train, _ = synthetic
    HybridModel(phys, window=2, hidden=(8,), seed=0, epochs=1).fit(train).save(tmp_path / "m")
    with open(tmp_path / "m" / "weights.pt", "wb") as f:
        torch.save({"x": _Evil()}, f, pickle_module=pickle)
    with pytest.raises(DataError, match="weights could not be loaded safely"):
        load_network(tmp_path / "m")


def test_learned_and_black_box_models(synthetic, panda, tmp_path):
    phys, train, test = synthetic
    # pure learning (no validation split: early stopping on the training loss) fits its data
    lt = LearnedTorqueModel(panda, window=3, hidden=(64, 64), seed=0, epochs=40, val_fraction=0.0, lr=3e-3,
                            batch_size=128).fit(train)
    s = ModelStructure(panda, joint_terms=())
    Y = np.vstack([s.target(t) for t in train])
    P = np.vstack([lt.predict(t) for t in train])
    assert np.all(np.sqrt(((P - Y) ** 2).mean(0)) < 0.3 * Y.std(0))
    assert lt.predict(test).shape == s.target(test).shape
    lstm = LearnedTorqueModel(panda, window=4, kind="lstm", hidden=(16,), seed=0, epochs=2, patience=2).fit(train)
    assert np.all(np.isfinite(lstm.predict(test)))

    # black box with user features (e.g. for a legged robot): configurable depth/width/activation
    def feats(traj):
        return np.hstack([np.sin(traj.q), np.cos(traj.q), traj.v])

    for act in ("leakyrelu", "tanh"):
        bb = MLPTorqueModel(hidden=(32,) * 5, activation=act, features=feats, seed=0, epochs=2, patience=2).fit(train)
        assert bb.architecture_["hidden"] == [32] * 5 and bb.predict(test).shape == test.tau.shape
    bb.save(tmp_path / "bb")
    with pytest.raises(DataError, match="pass the same callable"):
        MLPTorqueModel.load(tmp_path / "bb")
    np.testing.assert_array_equal(MLPTorqueModel.load(tmp_path / "bb", features=feats).predict(test), bb.predict(test))
    assert MLPTorqueModel().hidden == (2048,) * 5  # the legged-study default
    with pytest.raises(SensorlessError, match="unknown activation"):
        MLPTorqueModel(hidden=(4,), activation="swish", seed=0, epochs=1).fit(train)
    with pytest.raises(SensorlessError, match="unknown training option"):
        HybridModel(phys, epoch=3)
    assert TrainConfig().num_threads == 1


def test_training_leaves_the_global_torch_state_alone(synthetic):
    phys, train, test = synthetic
    torch.manual_seed(123)
    expected = torch.rand(3)
    torch.manual_seed(123)
    threads = torch.get_num_threads()
    hy = HybridModel(phys, window=2, hidden=(8,), seed=0, epochs=1).fit(train)
    hy.predict(test)
    assert torch.equal(torch.rand(3), expected)
    assert torch.get_num_threads() == threads and not torch.are_deterministic_algorithms_enabled()
