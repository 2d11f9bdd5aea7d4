"""The torque-model contract (sensorless.torque_models.TorqueModel): an ABC with fit/predict/score,
scikit-learn's parameter rules (``sklearn.base.clone`` gives an unfitted copy that fits to the
same model), and one scoring function."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")
sklearn_base = pytest.importorskip("sklearn.base")

from sensorless.errors import ParameterError  # noqa: E402
from sensorless.torque_models import CADModel, PhysicalModel, TorqueModel, score  # noqa: E402
from sensorless.excitation import random_fourier  # noqa: E402
from sensorless.identification import identify  # noqa: E402
from sensorless.learning import HybridModel, LearnedTorqueModel, MLPTorqueModel, ValidatedHybridModel  # noqa: E402
from sensorless.regressor import ModelStructure  # noqa: E402
from sensorless.testing import perturbed_truth, synthetic_trajectory  # noqa: E402

TINY = dict(seed=0, epochs=3, patience=2, batch_size=64)


@pytest.fixture(scope="module")
def logs(panda):
    truth = perturbed_truth(panda, rng=0)

    def log(seed):
        return synthetic_trajectory(truth, random_fourier(panda, rng=seed, base_freq=0.2).sample(50, 4.0),
                                    noise_std=0.05, rng=seed + 100)

    return [log(1), log(2)], log(3)


def _models(panda):
    return {
        "physical": PhysicalModel(panda, method="ols"),
        "mlp": MLPTorqueModel(hidden=(8,), window=2, **TINY),
        "learned": LearnedTorqueModel(panda, window=2, hidden=(8,), **TINY),
        "hybrid": HybridModel(PhysicalModel(panda), window=2, hidden=(8,), **TINY),
        "validated": ValidatedHybridModel(PhysicalModel(panda), window=2, hidden=(8,), min_gain=0.0, **TINY),
    }


def _learned_state(model) -> list[str]:
    return [k for k in vars(model) if k.endswith("_") and not k.startswith("_")]


def test_torque_model_is_an_abstract_base():
    with pytest.raises(TypeError):
        TorqueModel()
    assert all(issubclass(c, TorqueModel) for c in (PhysicalModel, CADModel, MLPTorqueModel, HybridModel))


@pytest.mark.parametrize("name", ["physical", "mlp", "learned", "hybrid", "validated"])
def test_init_sets_no_learned_state_and_stores_every_argument(panda, name):
    model = _models(panda)[name]
    assert _learned_state(model) == []
    names, var = model._init_signature()
    for key in names:  # stored as given (clone checks identity)
        assert key in vars(model)


@pytest.mark.parametrize("name", ["physical", "mlp", "learned", "hybrid", "validated"])
def test_sklearn_clone_gives_an_unfitted_copy_that_fits_to_the_same_model(panda, logs, name):
    train, test = logs
    model = _models(panda)[name].fit(train)
    copy = sklearn_base.clone(model)
    assert type(copy) is type(model) and copy is not model
    assert _learned_state(copy) == []
    a, b = model.get_params(deep=False), copy.get_params(deep=False)
    assert a.keys() == b.keys()
    for key in a:
        if hasattr(a[key], "get_params"):  # nested model: cloned too, unfitted
            assert b[key] is not a[key] and _learned_state(b[key]) == []
        else:
            assert b[key] == a[key]
    np.testing.assert_allclose(copy.fit(train).predict(test), model.predict(test), rtol=1e-6, atol=1e-6)


def test_get_params_deep_and_set_params(panda):
    hy = HybridModel(PhysicalModel(panda, method="ols"), window=2, hidden=(8,), epochs=5)
    deep = hy.get_params(deep=True)
    assert deep["physical_model__method"] == "ols" and deep["window"] == 2 and deep["epochs"] == 5
    hy.set_params(window=4, physical_model__method="wls", epochs=7)
    assert hy.window == 4 and hy.physical_model.method == "wls" and hy.train_config.epochs == 7
    with pytest.raises(ParameterError, match="no hyper-parameter"):
        CADModel(panda).set_params(nonsense=1)


def test_from_parameters_is_a_fitted_physical_model_and_clones(panda, logs):
    train, test = logs
    s = ModelStructure(panda)
    p = identify(s, train).parameters
    fixed = PhysicalModel.from_parameters(s, p)
    np.testing.assert_allclose(fixed.predict(test), s.torques(p, test))
    again = sklearn_base.clone(fixed).fit()  # the fixed parameters are a hyper-parameter: nothing to learn
    np.testing.assert_array_equal(again.predict(test), fixed.predict(test))
    with pytest.raises(ParameterError, match="expected"):
        PhysicalModel.from_parameters(s, p[:-1])


def test_one_scoring_function(panda, logs):
    train, test = logs
    phys = PhysicalModel(panda).fit(train)
    mlp = MLPTorqueModel(hidden=(8,), window=2, **TINY).fit(train)
    for model in (phys, mlp, CADModel(panda).fit()):
        m, ref = model.score(test), score(model, test)
        np.testing.assert_array_equal(m.rmse, ref.rmse)
    np.testing.assert_allclose(phys.score(test).nrmse, phys.result_.score(test).nrmse)


def test_cad_model_follows_sklearn_rules_and_clones(panda, logs):
    """CADModel sets nothing learned in __init__ (``like`` is stored as given); fit builds the
    prior; clone gives an unfitted copy that predicts the same after fit."""
    _, test = logs
    like = ModelStructure(panda, joint_terms=("fv", "fc"))
    cad = CADModel(panda, like=like)
    assert _learned_state(cad) == [] and cad.like is like
    with pytest.raises(AttributeError):
        cad.predict(test)  # not fitted
    cad.fit()
    copy = sklearn_base.clone(cad)
    assert _learned_state(copy) == [] and set(copy.get_params(deep=False)) == {"robot", "like"}
    np.testing.assert_array_equal(copy.fit().predict(test), cad.predict(test))
    # the baseline is the model file's own inertials: W(q, v, a) π_CAD, no friction
    np.testing.assert_allclose(cad.predict(test), ModelStructure(panda, joint_terms=("armature",)).torques(
        ModelStructure(panda, joint_terms=("armature",)).prior(), test))


def test_physical_model_fits_through_friction_and_precompressed_equations(panda, logs):
    train, test = logs
    s = ModelStructure(panda)
    from sensorless.regressor.compress import compress

    direct = identify(s, train, method="ols")
    from_ne = PhysicalModel(structure=s, method="ols").fit(compress(s, train))
    # the presented model is a conic solution: equal to the solver's precision (the two paths sum the same
    # equations in another order)
    np.testing.assert_allclose(from_ne.parameters_, direct.parameters, rtol=1e-6, atol=1e-8)
    fr = PhysicalModel(structure=s, method="ols", friction={"coulomb_smoothing": "auto"}).fit(train)
    assert fr.friction_fit_ is not None and fr.structure_ is fr.result_.structure
    assert np.all(fr.score(test).nrmse < 0.2)
    assert _learned_state(sklearn_base.clone(fr)) == []
