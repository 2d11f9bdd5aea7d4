"""Validated model folders (issue 26 item 5): one reader, a versioned schema, typed one-line errors.

Every command that applies a model (predict, estimate-force, payload, monitor) reads it through
:func:`sensorless.identification.artifact.load_model_folder`; a tampered result.json gets exit 2
and one line naming the key, never an internal error, a hang, or a file's content.
"""

from __future__ import annotations

import base64
import json
import os
import threading
import time

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.errors import DataError, InputError, ParameterError
from sensorless.excitation import random_fourier
from sensorless.identification.artifact import SCHEMA_VERSION, load_model_folder, read_result
from sensorless.testing import perturbed_truth, synthetic_trajectory

LOCK = ["--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]
ROBOT = ["--robot", "panda", *LOCK]
SECRET = "s3cret-line-never-printed"


def _run(args):
    r = CliRunner().invoke(app, [str(a) for a in args])
    return r.exit_code, r.output


@pytest.fixture(scope="module")
def panda_locked():
    from sensorless.robot import load_robot

    return load_robot("panda", lock_joints=("panda_finger_joint1", "panda_finger_joint2"))


@pytest.fixture(scope="module")
def models(tmp_path_factory, panda_locked):
    """Logs, and an OLS and an LMI model identified from them by the CLI."""
    d = tmp_path_factory.mktemp("artifact")
    truth = perturbed_truth(panda_locked, rng=0)
    tr = synthetic_trajectory(truth, random_fourier(panda_locked, rng=1).sample(100, 10.0), noise_std=0.1, rng=2)
    te = synthetic_trajectory(truth, random_fourier(panda_locked, rng=3).sample(100, 6.0), noise_std=0.1, rng=4)
    write_npz(tr, d / "train.npz")
    write_npz(te, d / "test.npz")
    for method in ("ols", "lmi"):
        code, out = _run(["identify", *ROBOT, "--data", d / "train.npz", "--method", method, "--gamma", "1e-4",
                          "--out", d / method, "--no-plot"] if method == "lmi" else
                         ["identify", *ROBOT, "--data", d / "train.npz", "--method", method, "--out", d / method,
                          "--no-plot"])
        assert code == 0, out
    return d


COMMANDS = {
    "predict": lambda m, d, o: ["predict", *ROBOT, "--model", m, "--data", d / "test.npz", "--out", o / "p.npz"],
    "estimate-force": lambda m, d, o: ["estimate-force", *ROBOT, "--model", m, "--data", d / "test.npz",
                                       "--frame", "panda_link7", "--out", o / "f.npz"],
    "payload": lambda m, d, o: ["payload", *ROBOT, "--model", m, "--data", d / "test.npz", "--frame", "panda_link7",
                                "--n-boot", "0", "--out", o / "pay.json"],
    "monitor": lambda m, d, o: ["monitor", *ROBOT, "--model", m, "--data", d / "test.npz", "--out", o / "mon"],
}

#: tampered settings.preprocessing values: (key or None for the whole object, value, text the error names)
TAMPERED = {
    "rate-string": ("rate", "100", "rate: expected a number"),
    "rate-negative": ("rate", -5, "rate"),
    "rate-zero": ("rate", 0, "rate"),
    "rate-1e9": ("rate", 1e9, "rate"),
    "rate-nan-string": ("rate", "NaN", "rate: expected a number"),
    "rate-boolean": ("rate", True, "rate"),
    "lowpass-tiny": ("lowpass", 1e-9, "lowpass"),
    "lowpass-string": ("lowpass", "abc", "lowpass"),
    "lowpass-negative": ("lowpass", -1, "lowpass"),
    "lowpass-huge": ("lowpass", 1e9, "lowpass"),
    "resample-1e9": ("resample", 1e9, "resample"),
    "resample-1e9-string": ("resample", "1e9", "resample"),
    "resample-word": ("resample", "fast", "resample"),
    "resample-list": ("resample", [1, 2], "resample"),
    "savgol-huge": ("savgol_window", 1000001, "savgol_window"),
    "savgol-even": ("savgol_window", 6, "savgol_window"),
    "savgol-string": ("savgol_window", "7", "savgol_window"),
    "savgol-fraction": ("savgol_window", 7.5, "savgol_window"),
    "columns-list": ("columns", ["q", "tau"], "columns"),
    "columns-nested": ("columns", {"q": {"a": 1}}, "columns.q"),
    "columns-unknown-field": ("columns", {"bogus": "x"}, "columns.bogus"),
    "columns-number": ("columns", 5, "columns"),
    "columns-gain-suffix": ("columns", {"tau": "i_{joint}:gain=/etc/passwd"}, "columns.tau"),
    "gains-word": ("gains", "abc", "gains"),
    "gains-zero": ("gains", 0, "gains"),
    "gains-huge": ("gains", [1e300], "gains[0]"),
    "time-unit-unknown": ("time_unit", "fortnight", "time_unit"),
    "time-unit-number": ("time_unit", 5, "time_unit"),
    "velocity-unknown": ("velocity", "psychic", "velocity"),
    "max-gap-negative": ("max_gap", -1, "max_gap"),
    "max-gap-string": ("max_gap", "big", "max_gap"),
    "trim-number": ("trim", 5, "trim"),
    "trim-words": ("trim", "a:b", "trim"),
    "rest-unknown": ("rest", "sometimes", "rest"),
    "decimate-zero": ("decimate", 0, "decimate"),
    "preprocessing-string": (None, "all", "settings.preprocessing"),
    "preprocessing-list": (None, [], "settings.preprocessing"),
    "gains-absolute-path": ("gains", "/etc/passwd", "gains: an absolute path"),
    "gains-escaping-path": ("gains", "../../x.csv", "gains: a path leading outside"),
}


def _tampered(models, tmp_path, mutate, name="m"):
    doc = json.loads((models / "lmi" / "result.json").read_text())
    mutate(doc)
    m = tmp_path / name
    m.mkdir()
    (m / "result.json").write_text(json.dumps(doc))
    return m


def _assert_one_line_error(code, out, *needles):
    text = out.strip()
    assert code == 2, text
    assert "internal error" not in text and "Traceback" not in text, text
    assert text.count("\n") <= 2, text  # one message (rich may wrap a long line)
    for n in needles:
        assert n in text.replace("\n", ""), text


@pytest.mark.parametrize("case", list(TAMPERED))
def test_tampered_preprocessing_is_one_typed_line_in_every_command(models, tmp_path, case):
    key, value, needle = TAMPERED[case]

    def mutate(doc):
        if key is None:
            doc["settings"]["preprocessing"] = value
        else:
            doc["settings"]["preprocessing"][key] = value

    m = _tampered(models, tmp_path, mutate)
    for cmd, args in COMMANDS.items():
        out_dir = tmp_path / cmd
        out_dir.mkdir()
        code, out = _run(args(m, models, out_dir))
        _assert_one_line_error(code, out, "result.json", needle)
        assert "root:" not in out, out
        assert not list(out_dir.iterdir()), f"{cmd} wrote output from a tampered model"


@pytest.mark.parametrize("mass", [-50.0, 1e150, 0.0])
def test_absurd_body_mass_is_refused_naming_the_body(models, tmp_path, mass):
    m = _tampered(models, tmp_path, lambda doc: doc["parameters"].update({"panda_joint3.m": mass}))
    for cmd, args in COMMANDS.items():
        out_dir = tmp_path / cmd
        out_dir.mkdir()
        code, out = _run(args(m, models, out_dir))
        _assert_one_line_error(code, out, "parameters.panda_joint3.m", "panda_joint3")


def test_inconsistent_body_and_negative_friction_in_an_lmi_model_are_refused(models, panda_locked, tmp_path):
    doc = json.loads((models / "lmi" / "result.json").read_text())
    Ixx = doc["parameters"]["panda_joint2.Ixx"]
    m = _tampered(models, tmp_path, lambda d: d["parameters"].update({"panda_joint2.Ixx": -abs(Ixx) - 1.0}), "a")
    with pytest.raises(ParameterError, match=r"parameters\.panda_joint2: body 'panda_joint2' is not physically"):
        load_model_folder(m, panda_locked)
    m = _tampered(models, tmp_path, lambda d: d["parameters"].update({"panda_joint4.fv": -0.5}), "b")
    with pytest.raises(ParameterError, match=r"parameters\.panda_joint4\.fv: fv = -0.5 is negative"):
        load_model_folder(m, panda_locked)


@pytest.mark.parametrize("mutate,needle", [
    (lambda d: d["settings"].update({"joint_terms": ["fv", "magic"]}), "settings.joint_terms[1]: unknown joint term"),
    (lambda d: d["settings"].update({"coulomb_smoothing": "x"}), "settings.coulomb_smoothing: expected a number"),
    (lambda d: d["settings"].update({"stribeck_velocity": {"panda_joint1": -1}}), "settings.stribeck_velocity.panda_joint1"),
    (lambda d: d["settings"].update({"rows": 7}), "settings.rows: expected a string"),
    (lambda d: d["parameters"].update({"extra.m": 1.0}), "parameters: 1 parameter(s) the model structure does not have"),
    (lambda d: d["parameters"].update({"panda_joint1.fv": "0.3"}), "parameters.panda_joint1.fv"),
    (lambda d: d.update({"schema_version": 99}), "schema_version 99 is newer"),
    (lambda d: d.update({"schema_version": "1"}), "schema_version: expected an integer"),
    (lambda d: d.update({"settings": []}), "settings: expected an object"),
])
def test_tampered_structure_and_parameters_name_the_key(models, panda_locked, tmp_path, mutate, needle):
    m = _tampered(models, tmp_path, mutate)
    with pytest.raises(ParameterError) as err:
        load_model_folder(m, panda_locked)
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_strict_json_duplicate_keys_and_size_are_refused(models, panda_locked, tmp_path):
    m = tmp_path / "m"
    m.mkdir()
    text = (models / "lmi" / "result.json").read_text()
    for bad, needle in ((text.replace('"schema_version": 1', '"schema_version": NaN', 1), "not a JSON number"),
                        ('{"a": 1, "a": 2}', "appears twice"), ("[1, 2]", "expected a JSON object"),
                        ("[" * 100000, "nested too deeply")):
        (m / "result.json").write_text(bad)
        with pytest.raises(ParameterError, match=needle):
            load_model_folder(m, panda_locked)
    from sensorless.io import read_json

    (m / "big.json").write_text("[" + "0," * 1000 + "0]")
    with pytest.raises(InputError, match="larger than the limit of 100 bytes"):
        read_json(m / "big.json", max_bytes=100)


def _finishes(fn, seconds):
    """(finished, result, elapsed): ``fn`` run in a daemon thread (a hang must not hang the suite)."""
    box = {}
    t0 = time.perf_counter()
    th = threading.Thread(target=lambda: box.update(r=fn()), daemon=True)
    th.start()
    th.join(seconds)
    return not th.is_alive(), box.get("r"), time.perf_counter() - t0


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_result_json_and_model_json_are_refused_quickly(models, tmp_path):
    m = tmp_path / "m"
    m.mkdir()
    os.mkfifo(m / "result.json")
    for cmd, args in COMMANDS.items():
        out_dir = tmp_path / cmd
        out_dir.mkdir()
        done, res, dt = _finishes(lambda: _run(args(m, models, out_dir)), 30)
        assert done, f"{cmd} hangs on a FIFO result.json"
        assert dt < 2.0, f"{cmd} took {dt:.1f} s"
        _assert_one_line_error(*res, "result.json", "FIFO")
    # a learned residual folder whose model.json is a FIFO (estimate-force --residual)
    pytest.importorskip("torch")
    res_dir = tmp_path / "residual"
    res_dir.mkdir()
    os.mkfifo(res_dir / "model.json")
    (res_dir / "weights.pt").write_bytes(b"")
    out_dir = tmp_path / "ef"
    out_dir.mkdir()
    done, res, dt = _finishes(lambda: _run([*COMMANDS["estimate-force"](models / "lmi", models, out_dir),
                                            "--residual", res_dir]), 60)
    assert done, "estimate-force hangs on a FIFO model.json"
    _assert_one_line_error(*res, "model.json", "FIFO")


def test_gains_file_content_never_appears_in_an_error(tmp_path):
    from sensorless.data.gains import load_gains

    for name, text in (("g.csv", f"{SECRET}\n"), ("g.txt", f"1.0,{SECRET},2.0\n"),
                       ("g.json", json.dumps({"j1": SECRET}))):
        (tmp_path / name).write_text(text)
        with pytest.raises(DataError) as err:
            load_gains(tmp_path / name)
        assert SECRET not in str(err.value) and name in str(err.value)
    if os.path.exists("/etc/passwd"):
        first = open("/etc/passwd").readline().strip()
        with pytest.raises(DataError) as err:
            load_gains("/etc/passwd")
        assert first not in str(err.value) and first.split(":")[0] + ":" not in str(err.value)
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "fifo.csv")
        done, _, _ = _finishes(lambda: pytest.raises(DataError, load_gains, tmp_path / "fifo.csv"), 10)
        assert done


def test_a_gains_file_inside_the_model_folder_is_followed(models, tmp_path, panda_locked):
    m = _tampered(models, tmp_path, lambda d: d["settings"]["preprocessing"].update({"gains": "drive/gains.json"}))
    (m / "drive").mkdir()
    (m / "drive" / "gains.json").write_text(json.dumps({j: 2.0 for j in panda_locked.actuated_joints}))
    art = load_model_folder(m, panda_locked)
    assert art.preprocessing["gains"] == str(m / "drive" / "gains.json")
    m2 = _tampered(models, tmp_path, lambda d: d["settings"]["preprocessing"].update({"gains": "drive/link.csv"}), "m2")
    (m2 / "drive").mkdir()
    os.symlink("/etc/passwd", m2 / "drive" / "link.csv")
    with pytest.raises(ParameterError, match="leading outside the model folder"):
        load_model_folder(m2, panda_locked)


def test_every_writer_stamps_the_schema_version_and_the_validator_accepts_it(models, panda_locked, tmp_path):
    for method in ("ols", "lmi"):
        doc = read_result(models / method)
        assert doc["schema_version"] == SCHEMA_VERSION
        art = load_model_folder(models / method, panda_locked)
        assert art.schema_version == SCHEMA_VERSION and art.parameters.shape == (len(art.structure.labels),)
        assert art.doc["method"] == method
    # a file written before the schema had a version (version 0) still loads when it validates
    legacy = _tampered(models, tmp_path, lambda d: d.pop("schema_version"))
    assert load_model_folder(legacy, panda_locked).schema_version == 0


@pytest.mark.slow
def test_demo_output_validates(tmp_path, panda_locked):
    code, out = _run(["demo", "--out", tmp_path / "demo"])
    assert code == 0, out
    art = load_model_folder(tmp_path / "demo", panda_locked)
    assert art.schema_version == SCHEMA_VERSION


def test_identify_with_the_robots_own_urdf_as_prior_and_default_joint_terms(models, tmp_path):
    """Regression: the prior was built for the structure with Stribeck terms, then the search dropped them
    ('prior has shape (105,), expected (98,)')."""
    from example_robot_data.robots_loader import PandaLoader, getModelPath

    rel = os.path.join(PandaLoader.path, PandaLoader.urdf_subpath, PandaLoader.urdf_filename)
    urdf = os.path.join(getModelPath(rel), rel)
    code, out = _run(["identify", "--robot", "panda", *LOCK, "--data", models / "train.npz", "--prior", urdf,
                      "--gamma", "1e-4", "--no-plot", "--out", tmp_path / "o"])
    assert code == 0, out
    doc = json.loads((tmp_path / "o" / "result.json").read_text())
    assert doc["settings"]["prior"] == "given"


def test_carry_prior_moves_values_by_label(panda_locked):
    from sensorless.identification.stribeck import carry_prior
    from sensorless.regressor import ModelStructure

    before = ModelStructure(panda_locked, joint_terms=("fv", "fc", "stribeck", "offset", "armature"))
    after = ModelStructure(panda_locked, joint_terms=("fv", "fc", "offset", "armature"))
    prior = np.arange(before.n_params, dtype=float)
    moved = carry_prior(prior, before, after)
    assert moved.shape == (after.n_params,)
    lookup = dict(zip(before.labels, prior))
    assert all(moved[i] == lookup[lab] for i, lab in enumerate(after.labels))
    assert carry_prior(None, before, after) is None


def test_no_second_reader_of_result_json_remains():
    """Every read of a model's result.json goes through sensorless.identification.artifact."""
    import pathlib
    import re

    root = pathlib.Path(__file__).resolve().parents[1]
    srcs = (root / "src" / "sensorless", root / "studies" / "src" / "sensorless_studies")
    pat = re.compile(r"json\.loads?\(.*(result\.json|result_json|model_path)")
    bad = [f"{p.relative_to(root)}:{i}" for src in srcs for p in src.rglob("*.py") if p.name not in ("artifact.py",)
           for i, line in enumerate(p.read_text().splitlines(), 1) if pat.search(line)]
    assert bad == [], bad


def test_no_second_writer_of_a_model_folder_remains():
    """Every result.json, model.urdf and joint_terms.json of a model folder is written by
    sensorless.identification.artifact (save_model_folder / write_result)."""
    import pathlib
    import re

    root = pathlib.Path(__file__).resolve().parents[1]
    srcs = (root / "src" / "sensorless", root / "studies" / "src" / "sensorless_studies")
    pat = re.compile(r"(write|save|dump)\w*\(.*[\"'](result\.json|model\.urdf|joint_terms\.json)[\"']")
    bad = [f"{p.relative_to(root)}:{i}" for src in srcs for p in src.rglob("*.py") if p.name != "artifact.py"
           for i, line in enumerate(p.read_text().splitlines(), 1) if pat.search(line)]
    assert bad == [], bad


def test_demo_result_json_is_the_model_of_its_urdf(tmp_path, panda_locked):
    """make demo used to write an OLS result.json next to an LMI model.urdf."""
    from sensorless.robot import load_robot

    code, out = _run(["demo", "--out", tmp_path / "demo"])
    assert code == 0, out
    art = load_model_folder(tmp_path / "demo", panda_locked)
    assert art.doc["method"] == "lmi" and art.doc["urdf"] == "model.urdf"
    page = (tmp_path / "demo" / "report.html").read_text()  # make demo writes the one-page report, plots embedded
    assert "Bodies: prior against identified" in page and "Held-out: validate.npz" in page
    for png in ("torques.png", "friction.png"):
        assert base64.b64encode((tmp_path / "demo" / png).read_bytes()).decode() in page
    urdf = load_robot(tmp_path / "demo" / "model.urdf")  # written without the locked fingers
    nb = art.structure.n_body_params
    from sensorless.excitation import random_fourier

    traj = random_fourier(panda_locked, rng=5).sample(50, 2.0)
    from sensorless.regressor import ModelStructure

    s = ModelStructure(urdf, joint_terms=())
    ref = ModelStructure(panda_locked, joint_terms=()).torques(art.parameters[:nb], traj)
    got = s.torques(urdf.inertial_parameters(), traj)
    assert np.allclose(got, ref, atol=1e-6 * np.abs(ref).max()), np.abs(got - ref).max()
