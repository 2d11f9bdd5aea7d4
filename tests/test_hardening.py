"""Issue 12 regressions: no silent garbage, typed one-line errors for every bad input.

One test per finding: unidentifiable parameters (relative std, joint motion, sample count
for every method), gross outliers (error / drop), reader, option and model-loading escapes.
"""

from __future__ import annotations

import json
import warnings
import zipfile

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import KUKA, REALDATA
from sensorless.cli import app
from sensorless.data import Trajectory, read_trajectory, write_npz
from sensorless.data.outliers import OUTLIER_THRESHOLD, find_outliers
from sensorless.errors import (
    DataError,
    ExcitationError,
    IdentifiabilityWarning,
    OptionError,
    OutlierError,
    ParameterError,
    RobotModelError,
    RobotModelWarning,
    SensorlessError,
    UnitsError,
)
from sensorless.excitation import random_fourier
from sensorless.identification import identify
from sensorless.testing import perturbed_truth, synthetic_trajectory

runner = CliRunner()
ROBOT = ["--robot", "panda", "--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]
JOINT = 5  # panda_joint6


@pytest.fixture(scope="module")
def sim(panda):
    truth = perturbed_truth(panda, rng=0)
    motion = random_fourier(panda, rng=1).sample(100, 10.0)
    train = synthetic_trajectory(truth, motion, noise_std=0.1, rng=2)
    test = synthetic_trajectory(truth, random_fourier(panda, rng=3).sample(100, 10.0), noise_std=0.1, rng=4)
    return truth, motion, train, test


def _shrink(motion: Trajectory, factor: float) -> Trajectory:
    """The same motion with joint JOINT's excursion about its mean scaled by ``factor``."""
    q, v, a = motion.q.copy(), motion.v.copy(), motion.a.copy()
    c = q[:, JOINT].mean()
    q[:, JOINT] = c + factor * (q[:, JOINT] - c)
    v[:, JOINT] *= factor
    a[:, JOINT] *= factor
    return motion.with_(q=q, v=v, a=a)


def _run(args):
    return runner.invoke(app, [str(a) for a in args])


def _one_line_error(r, *needles):
    assert r.exit_code != 0, r.output
    text = r.output.strip()
    assert text.count("\n") == 0, text
    assert "Traceback" not in text and "internal error" not in text, text
    for n in needles:
        assert n in text, text


# ---- High 3: unidentifiable parameters ---------------------------------------------------
@pytest.mark.parametrize("method", ["ols", "svd", "lmi"])
def test_joint_moving_1e4_rad_is_an_excitation_error_for_every_method(panda, sim, method):
    """The issue's case: joint moves 1e-4 rad -> armature 66 (true 0.04) silently. Now refused."""
    truth, motion, _, _ = sim
    still = synthetic_trajectory(truth, _shrink(motion, 1e-4), noise_std=0.1, rng=2)
    assert np.ptp(still.q[:, JOINT]) < 1e-3
    with pytest.raises(ExcitationError, match="panda_joint6.*do not move"):
        identify(panda, still, method=method, gamma=1e-3)


@pytest.mark.parametrize("method", ["ols", "wls", "svd", "lmi"])
def test_three_sample_log_is_refused_by_every_method(panda, sim, method):
    with pytest.raises(ExcitationError, match="samples"):
        identify(panda, sim[2].take(slice(0, 3)), method=method, gamma=1e-3)


def test_barely_moving_joint_warns_with_relative_std_in_diagnostics(panda, sim):
    """Range 0.024 rad: armature 3x off. Its fv/armature are flagged by relative std > 100 %."""
    truth, motion, _, _ = sim
    slow = synthetic_trajectory(truth, _shrink(motion, 1e-2), noise_std=0.1, rng=2)
    with pytest.warns(IdentifiabilityWarning, match="panda_joint6"):
        res = identify(panda, slow)
    d = res.diagnostics
    flagged = {p["base_parameter"] for p in d["poorly_identified"]}
    assert {"panda_joint6.armature", "panda_joint6.fv"} <= flagged
    assert all(p["relative_std"] is None or p["relative_std"] > 1.0 for p in d["poorly_identified"])
    assert len(d["base_relative_std"]) == res.base.rank
    assert any("barely move" in w and "panda_joint6" in w for w in d["warnings"])
    json.dumps(d, allow_nan=False)  # the new diagnostics are valid JSON


def test_well_excited_log_has_no_identifiability_warning_and_std_matches_error(panda, sim):
    truth, _, train, _ = sim
    with warnings.catch_warnings():
        warnings.simplefilter("error", IdentifiabilityWarning)
        res = identify(panda, train)
    assert res.diagnostics["poorly_identified"] == [] and res.diagnostics["warnings"] == []
    # the reported std is the real spread: base-parameter errors are within 5 sigma
    err = res.base_values - res.base.base(truth.parameters(res.structure.joint_terms))
    std = np.array(res.diagnostics["base_std"])
    assert np.all(np.abs(err) < 5 * std)


def test_cli_warns_and_writes_poorly_identified_to_result_json(panda, sim, tmp_path):
    truth, motion, _, _ = sim
    write_npz(synthetic_trajectory(truth, _shrink(motion, 1e-2), noise_std=0.1, rng=2), tmp_path / "slow.npz")
    r = _run(["identify", *ROBOT, "--data", tmp_path / "slow.npz", "--out", tmp_path / "o"])
    assert r.exit_code == 0, r.output
    assert "warning:" in r.output and "panda_joint6.armature" in r.output
    doc = json.loads((tmp_path / "o" / "result.json").read_text())
    assert any(p["base_parameter"] == "panda_joint6.armature" for p in doc["diagnostics"]["poorly_identified"])
    assert doc["diagnostics"]["warnings"]


# ---- High 4: outliers -----------------------------------------------------------------
@pytest.mark.parametrize("glitch", [1e10, 1e20, 1e30])
def test_one_glitched_torque_is_an_outlier_error_naming_file_column_sample(sim, tmp_path, glitch):
    tr = sim[2]
    tau = tr.tau.copy()
    tau[417, 2] = glitch
    f = write_npz(tr.with_(tau=tau), tmp_path / "glitch.npz")
    with pytest.raises(OutlierError, match=r"glitch.npz: 'tau' column 'panda_joint3' .* sample 417"):
        read_trajectory(f)
    with pytest.raises(OutlierError, match="sample 417"):
        identify(sim[2].joint_names and _panda(), tr.with_(tau=tau))


def _panda():
    from sensorless.robot import load_robot

    return load_robot("panda", lock_joints=["panda_finger_joint1", "panda_finger_joint2"])


def test_outliers_drop_recovers_clean_parameters(panda, sim, tmp_path):
    truth, _, tr, te = sim
    tau = tr.tau.copy()
    tau[417, 2] = 1e27
    with pytest.warns(Warning, match="dropped 1 outlier sample"):
        res = identify(panda, tr.with_(tau=tau), outliers="drop")
    clean = identify(panda, tr)
    assert res.diagnostics["n_samples"] == len(tr) - 1
    assert np.max(np.abs(res.parameters)) < 1e3
    np.testing.assert_allclose(res.score(te).rmse.mean(), clean.score(te).rmse.mean(), rtol=0.05)
    # CLI: default refuses with a one-line error, --outliers drop succeeds with a warning
    f = write_npz(tr.with_(tau=tau), tmp_path / "g.npz")
    _one_line_error(_run(["identify", *ROBOT, "--data", f, "--out", tmp_path / "o1"]), "sample 417", "g.npz")
    r = _run(["identify", *ROBOT, "--data", f, "--outliers", "drop", "--out", tmp_path / "o2"])
    assert r.exit_code == 0 and "dropped 1 outlier" in r.output, r.output
    doc = json.loads((tmp_path / "o2" / "result.json").read_text())
    assert max(abs(v) for v in doc["parameters"].values()) < 1e3


def test_outlier_threshold_does_not_fire_on_real_logs(kuka):
    files = sorted((KUKA / "data" / "KUKA" / "HW").glob("*.npz"))
    csvs = sorted((REALDATA / "dvrk_psm_wpi" / "data" / "psm" / "measured_trajectory").glob("*.csv"))
    if not files and not csvs:
        pytest.skip("real data not available")
    logs = [read_trajectory(f, robot=kuka, outliers="keep") for f in files]
    logs += [read_trajectory(f, columns={"q": "0:7", "v": "7:14", "tau": "14:21"}, rate=200, outliers="keep")
             for f in csvs]
    for tr in logs:
        assert find_outliers(tr) == []
        # and there is a wide margin: not even at 1/100 of the threshold
        assert find_outliers(tr, OUTLIER_THRESHOLD / 100) == [], tr.source


# ---- Medium: readers --------------------------------------------------------------------
def test_corrupt_npz_member_is_a_data_error(sim, tmp_path):
    f = write_npz(sim[2], tmp_path / "ok.npz")
    raw = bytearray(f.read_bytes())
    with zipfile.ZipFile(f) as z:
        info = z.getinfo("torques.npy")
    # recompress with deflate, then flip bytes inside the deflated member (zlib.error on read)
    z2 = tmp_path / "bad.npz"
    with zipfile.ZipFile(f) as zin, zipfile.ZipFile(z2, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            zout.writestr(item.filename, zin.read(item.filename))
    data = bytearray(z2.read_bytes())
    with zipfile.ZipFile(z2) as z:
        off = z.getinfo("positions.npy").header_offset + 30 + len("positions.npy") + 20
    data[off:off + 40] = b"\xff" * 40
    z2.write_bytes(bytes(data))
    with pytest.raises(DataError, match="bad.npz"):
        read_trajectory(z2)
    assert info.file_size > 0 and raw


def test_corrupt_hdf5_is_a_data_error(sim, tmp_path):
    f = tmp_path / "log.h5"
    with h5py.File(f, "w") as h:
        h["positions"] = sim[2].q
        h["times"] = sim[2].t
    data = bytearray(f.read_bytes())
    data[len(data) // 2:] = b"\x00" * (len(data) - len(data) // 2)
    f.write_bytes(bytes(data))
    with pytest.raises(DataError, match="log.h5"):
        read_trajectory(f)


@pytest.mark.parametrize("key", ["contact", "imu_acc"])
def test_object_array_in_contact_or_imu_is_a_data_error(sim, tmp_path, key):
    tr = sim[2]
    f = tmp_path / "obj.npz"
    arrays = {"times": tr.t, "positions": tr.q, key: np.array([None] * len(tr), dtype=object)}
    with open(f, "wb") as fh:
        np.savez(fh, **arrays)  # object arrays are pickled; the reader refuses pickles
    with pytest.raises(DataError, match="obj.npz"):
        read_trajectory(f)


@pytest.mark.parametrize("values,what", [
    (lambda q: q > 0, "boolean"),
    (lambda q: q + 1j, "complex"),
    (lambda q: np.zeros(q.shape, dtype="datetime64[s]"), "datetime"),
])
def test_bool_complex_datetime_arrays_are_refused(sim, tmp_path, values, what):
    tr = sim[2]
    f = tmp_path / "typed.npz"
    with open(f, "wb") as fh:
        np.savez(fh, times=tr.t, positions=values(tr.q))
    with pytest.raises(DataError, match=what):
        read_trajectory(f)
    with pytest.raises(DataError, match=what):
        Trajectory(t=tr.t, q=values(tr.q), joint_names=tr.joint_names)


def test_joint_names_shorter_than_columns(sim, tmp_path):
    tr = sim[2]
    f = tmp_path / "names.npz"
    with open(f, "wb") as fh:
        np.savez(fh, times=tr.t, positions=tr.q, joint_names=np.array(tr.joint_names[:3]))
    with pytest.raises(DataError, match=r"joint names are 3 \(.*\) but 'q' \('positions'\) has 7 columns.*`columns="):
        read_trajectory(f)


def test_identify_validates_a_raw_trajectory(panda, sim):
    tr = sim[2]
    q = tr.q.copy()
    q[10, 1] = np.nan
    with pytest.raises(DataError, match="panda_joint2.*sample 10"):
        identify(panda, tr.with_(q=q))
    t = tr.t.copy()
    t[20] = t[19]
    with pytest.raises(DataError, match="duplicate timestamp"):
        identify(panda, tr.with_(t=t))
    with pytest.raises(DataError, match="missing joint"):
        identify(panda, tr.select_joints(list(tr.joint_names[:6])))


def test_huge_torques_are_a_units_error_not_linalgerror(panda, sim):
    tr = sim[2]
    with pytest.raises(UnitsError, match="tau"):
        identify(panda, tr.with_(tau=np.full_like(tr.tau, 1e300)))


# ---- Medium: options ------------------------------------------------------------------------
@pytest.mark.parametrize("opts,needle", [
    (["--rate", "1e300"], "--rate"), (["--rate", "1e-300"], "--rate"),
    (["--gamma", "nan", "--method", "lmi"], "--gamma"), (["--coulomb-smoothing", "nan"], "--coulomb-smoothing"),
    (["--regularization", "bogus"], "--regularization"), (["--decimate", "0"], "--decimate"),
    (["--decimate", "-2"], "--decimate"), (["--savgol-window", "0"], "--savgol-window"),
    (["--lowpass", "0"], "--lowpass"), (["--lowpass", "-5"], "--lowpass"), (["--outliers", "ignore"], "--outliers"),
])
def test_bad_option_values_are_one_line_errors(sim, tmp_path, opts, needle):
    f = write_npz(sim[2], tmp_path / "t.npz")
    out = tmp_path / "o"
    _one_line_error(_run(["identify", *ROBOT, "--data", f, *opts, "--out", out]), needle)
    assert not out.exists()


def test_absurd_rates_in_the_python_api(sim, tmp_path):
    import pandas as pd

    f = tmp_path / "norate.csv"
    pd.DataFrame(sim[2].q).to_csv(f, header=False, index=False)
    for rate in (1e300, 1e-300, float("nan"), -1.0):
        with pytest.raises(DataError, match="rate"):
            read_trajectory(f, columns={"q": "0:7"}, rate=rate)


@pytest.mark.parametrize("kw", [{"gamma": float("nan")}, {"gamma": -1.0}, {"regularization": "bogus"},
                                {"outliers": "maybe"}, {"chunk": 0}, {"svd_rcond": float("nan")}])
def test_bad_identify_keywords_are_option_errors(panda, sim, kw):
    with pytest.raises(OptionError):
        identify(panda, sim[2], method="lmi", **kw)


# ---- Medium: model loading --------------------------------------------------------------------
_URDF = """<robot name="r"><link name="base"/>
<link name="l1"><inertial><mass value="{mass}"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="0.01"/></inertial></link>
<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="{axis}"/>
<limit lower="{lo}" upper="1" effort="10" velocity="2"/></joint></robot>"""


@pytest.mark.parametrize("fields,needle", [
    ({"mass": "nan"}, "mass is not finite"), ({"mass": "heavy"}, "mass is not a number"),
    ({"axis": "0 0 0"}, "zero-length axis"), ({"lo": "2"}, "lower limit 2 above upper limit 1"),
])
def test_bad_urdf_values_are_robot_model_errors(tmp_path, fields, needle):
    from sensorless.robot import load_robot

    f = tmp_path / "r.urdf"
    f.write_text(_URDF.format(**{"mass": "1", "iyy": "0.01", "axis": "0 0 1", "lo": "-1", **fields}))
    with pytest.raises(RobotModelError, match=needle):
        load_robot(f)


def test_non_psd_urdf_inertia_warns(tmp_path):
    from sensorless.robot import load_robot

    f = tmp_path / "r.urdf"
    f.write_text(_URDF.format(mass="1", iyy="-0.5", axis="0 0 1", lo="-1"))
    with pytest.warns(RobotModelWarning, match="not positive semi-definite"):
        load_robot(f)


def test_urdfdom_error_is_one_line_in_the_cli(tmp_path):
    f = tmp_path / "broken.urdf"
    f.write_text('<robot name="x"><link name="a"/><joint name="j" type="revolute"><parent link="a"/>'
                 '<child link="zz"/></joint></robot>')
    g = tmp_path / "x.npz"
    r = _run(["identify", "--robot", f, "--data", g, "--out", tmp_path / "o"])
    _one_line_error(r, "broken.urdf")
    f.write_text("<robot><link name=")  # not XML at all
    _one_line_error(_run(["identify", "--robot", f, "--data", g, "--out", tmp_path / "o"]), "not well-formed")


@pytest.fixture(scope="module")
def identified(sim, tmp_path_factory):
    d = tmp_path_factory.mktemp("model")
    f = write_npz(sim[2], d / "train.npz")
    assert _run(["identify", *ROBOT, "--data", f, "--out", d / "run"]).exit_code == 0
    return d, f


@pytest.mark.parametrize("mutate,needle", [
    (lambda doc: doc["parameters"].update({"panda_joint1.m": float("nan")}), "'NaN' is not a JSON number"),
    (lambda doc: doc["parameters"].update({"panda_joint1.m": "heavy"}), "not finite"),
    (lambda doc: doc.update({"settings": []}), "settings: expected an object"),
    (lambda doc: doc["settings"].update({"joint_terms": 3}), "settings.joint_terms: expected a list"),
    (lambda doc: doc["settings"].update({"joint_terms": ["bogus"]}), "settings.joint_terms[0]: unknown joint term"),
])
def test_malformed_or_nan_result_json_is_refused_by_predict(identified, tmp_path, mutate, needle):
    d, f = identified
    doc = json.loads((d / "run" / "result.json").read_text())
    mutate(doc)
    bad = tmp_path / "result.json"
    bad.write_text(json.dumps(doc))
    _one_line_error(_run(["predict", *ROBOT, "--model", bad, "--data", f, "--out", tmp_path / "p.npz"]), needle)
    assert not (tmp_path / "p.npz").exists()
    with pytest.raises(ParameterError):
        from sensorless.torque_models import load_parameters

        load_parameters(bad, _panda())


def test_truncated_result_json_is_refused(identified, tmp_path):
    d, f = identified
    bad = tmp_path / "result.json"
    bad.write_text((d / "run" / "result.json").read_text()[:500])
    _one_line_error(_run(["predict", *ROBOT, "--model", bad, "--data", f, "--out", tmp_path / "p.npz"]),
                    "not valid JSON")


def test_model_json_sizes_are_bounded(tmp_path):
    pytest.importorskip("torch")
    from sensorless.learning.io import load_network

    (tmp_path / "weights.pt").write_bytes(b"")
    for arch in ({"kind": "mlp", "in_dim": 200000, "out_dim": 7, "hidden": [200000, 200000]},
                 {"kind": "mlp", "in_dim": -1, "out_dim": 7, "hidden": [8]},
                 {"kind": "mlp", "in_dim": 3, "out_dim": 7, "hidden": "big"},
                 {"kind": "lstm", "in_dim": 30, "out_dim": 7, "hidden": [10 ** 9], "window": 3}):
        (tmp_path / "model.json").write_text(json.dumps({"architecture": arch}))
        with pytest.raises(DataError, match="model.json"):
            load_network(tmp_path)


def test_parameters_module_raises_typed_value_errors():
    from sensorless import parameters as P

    for call in (lambda: P.as_bodies(np.zeros(7)), lambda: P.inertia_matrix(np.zeros(9)),
                 lambda: P.from_pseudo_inertia(np.zeros((3, 3))), lambda: P.urdf_inertial(np.zeros((2, 10))),
                 lambda: P.check_physical_consistency(np.zeros(20), ["a"]),
                 lambda: P.JointTerms(("a",), fv=[1.0, 2.0]), lambda: P.JointTerms.from_dict({"a": {"zz": 1}}),
                 lambda: P.from_urdf_inertial({"mass": "nan"})):
        with pytest.raises(ParameterError) as exc:
            call()
        assert isinstance(exc.value, ValueError) and isinstance(exc.value, SensorlessError)


def test_corrupt_npy_header_is_a_data_error(tmp_path):
    """Found by benchmarks/fuzz.py: numpy's header parser raised tokenize.TokenError."""
    import io

    buf = io.BytesIO()
    np.save(buf, np.zeros((5, 2)))
    f = tmp_path / "hdr.npz"
    with zipfile.ZipFile(f, "w") as z:
        z.writestr("positions.npy", buf.getvalue().replace(b"'shape': (5, 2)", b"'shape': ((5, 2)"))
    with pytest.raises(DataError, match="hdr.npz.*TokenError"):
        read_trajectory(f, rate=100.0)


def test_zero_dimensional_positions_are_a_shape_error(tmp_path):
    """Found by the hypothesis fuzz test: a 0-D 'positions' array raised IndexError."""
    f = tmp_path / "scalar.npz"
    with open(f, "wb") as fh:
        np.savez(fh, positions=np.array(0.0))
    with pytest.raises(DataError, match="0-D"):
        read_trajectory(f, rate=100.0)
