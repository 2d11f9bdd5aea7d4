"""`identify --config run.toml` and the choice options (sensorless.cli.options)."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.cli import options as opts
from sensorless.data import write_npz
from sensorless.excitation import random_fourier
from sensorless.testing import perturbed_truth, synthetic_trajectory

runner = CliRunner()


@pytest.fixture(scope="module")
def log(tmp_path_factory, ur5):
    d = tmp_path_factory.mktemp("cfg")
    truth = perturbed_truth(ur5, rng=0)
    write_npz(synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(100, 8.0), noise_std=0.1, rng=2),
              d / "train.npz")
    return d / "train.npz"


def test_config_file_maps_onto_options_command_line_wins_and_is_saved(log, tmp_path):
    cfg = tmp_path / "run.toml"
    cfg.write_text(f'robot = "ur5"\ndata = ["{log}"]\nmethod = "wls"\njoint-terms = "fv,offset"\n'
                   'plot = false\nsavgol_window = 21\n')
    r = runner.invoke(app, ["identify", "--config", str(cfg), "--method", "ols", "--out", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    settings = json.loads((tmp_path / "o" / "result.json").read_text())["settings"]
    saved = settings["config"]
    assert saved["file"] == str(cfg)
    assert saved["options"]["method"] == "ols"  # the command line overrides the file
    assert saved["options"]["joint_terms"] == "fv,offset" and saved["options"]["savgol_window"] == 21
    assert saved["options"]["data"] == [str(log)] and saved["options"]["plot"] is False
    assert settings["joint_terms"] == ["fv", "offset"] and settings["method"] == "ols"
    assert not (tmp_path / "o" / "torques.png").exists()


@pytest.mark.parametrize("text, match", [('metod = "lmi"\n', "unknown key.*metod"),
                                         ("method = [\n", "not a readable TOML file")])
def test_bad_config_is_one_line_option_error_and_no_output(log, tmp_path, text, match):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(text)
    out = tmp_path / "o"
    r = runner.invoke(app, ["identify", "--config", str(cfg), "--robot", "ur5", "--data", str(log), "--out", str(out)])
    assert r.exit_code == 2
    assert len(r.output.strip().splitlines()) == 1 and "--config" in r.output
    import re

    assert re.search(match, r.output)
    assert not out.exists()


def test_free_string_options_are_choices(log, tmp_path):
    r = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(log), "--out", str(tmp_path / "o"),
                            "--method", "lsq"])
    assert r.exit_code == 2 and "'lsq' is not one of" in r.output and not (tmp_path / "o").exists()


@pytest.mark.parametrize("args, bad", [
    (["excite", "--robot", "ur5", "--criterion", "aopt"], "aopt"),
    (["experiment", "psm-identify", "--save", "svd"], "svd"),
    (["experiment", "contact-id", "--training", "walk"], "walk"),
])
def test_study_choices_are_refused_before_running(args, bad, tmp_path):
    out = tmp_path / "o"
    r = runner.invoke(app, args + ["--out", str(out)])
    assert r.exit_code == 2 and f"'{bad}' is not one of" in r.output and not out.exists()


def test_choices_mirror_the_library():
    from sensorless.data.outliers import OUTLIER_MODES
    from sensorless.data.prepare import VELOCITY_SOURCES
    from sensorless.identification import METHODS
    from sensorless.identification.regularizers import REGULARIZERS
    from sensorless.regressor.contact import WRENCH_OFFSETS

    assert set(opts.Method) == set(METHODS)
    assert set(opts.Regularization) == {*REGULARIZERS, "none"}
    assert tuple(opts.Outliers) == OUTLIER_MODES and tuple(opts.Velocity) == VELOCITY_SOURCES
    assert tuple(opts.WrenchOffset) == WRENCH_OFFSETS
    assert f"{opts.Method.lmi}" == "lmi" and opts.Velocity("from-q") == "from-q"


def test_study_and_estimator_choices_mirror_the_library():
    from sensorless.estimation.force import COMPONENTS, REFERENCES
    from sensorless.excitation.criteria import CRITERIA
    from sensorless_studies.experiments.contact_id import ACCELERATIONS, TRAININGS
    from sensorless.identification import METHODS
    from sensorless.data.align import ALIGNMENTS
    from sensorless.identification.payload import MODES
    from sensorless_studies.simulation.quadruped import TAU_LOGS

    assert tuple(opts.Criterion) == CRITERIA and tuple(opts.PayloadMode) == MODES
    assert set(opts.ForceReference) == set(REFERENCES) and COMPONENTS == ("linear", "angular", "wrench")
    assert tuple(opts.Align) == ALIGNMENTS and tuple(opts.Training) == TRAININGS and tuple(opts.TauLog) == TAU_LOGS
    assert set(opts.Acceleration) == {*ACCELERATIONS, "logged"}  # logged: the simulator's own, an alias
    assert set(opts.LinearMethod) < set(opts.PsmModel) <= set(METHODS)
