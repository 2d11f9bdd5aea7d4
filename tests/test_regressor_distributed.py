"""Fleet-scale identification on Dask (issue 16): same result as the local path, typed
errors naming the bad file, --skip-bad reporting, retries, and a worker killed mid-run."""

from __future__ import annotations

import json
import logging
import os
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

distributed = pytest.importorskip("distributed")

from sensorless_studies.simulation.fleet_logs import write_fleet_logs  # noqa: E402
from sensorless.cli import app  # noqa: E402
from sensorless.run.logs import load_logs  # noqa: E402
from sensorless.errors import DataError, JointNameError  # noqa: E402
from sensorless.identification import identify, identify_files  # noqa: E402
from sensorless.identification.gamma import split_folds  # noqa: E402
from sensorless.regressor import ModelStructure, compress, compress_files, expand_paths  # noqa: E402
from sensorless.regressor.dask_cluster import connect  # noqa: E402
from sensorless.regressor.distributed import LogReader, PickledModel, worker_structure  # noqa: E402
from sensorless.errors import DistributedError  # noqa: E402

TOL = 1e-10
#: parameters after identify's presented model (identification/presented.py): a conic solution, equal across
#: paths to the solver's precision (the equations are summed in another order)
TOL_PRESENTED = 1e-6
ROBOT = ["--robot", "panda", "--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]


def _rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


@pytest.fixture(scope="module")
def fleet(tmp_path_factory, panda):
    """4 Parquet logs (3000 samples each, > one 2048-sample chunk) in two sub-directories."""
    d = tmp_path_factory.mktemp("fleet")
    paths = write_fleet_logs(panda, d, 4, 3000, rate=500.0, base_freq=0.1, subdirs=2, seed=3)
    files = expand_paths([d / "**" / "*.parquet"])
    assert sorted(map(str, files)) == sorted(map(str, paths))  # the glob finds every written log
    return d, files


@pytest.fixture(scope="module")
def structure(panda):
    return ModelStructure(panda)


@pytest.fixture(scope="module")
def client():
    """Two in-process workers, one thread each (fast to start)."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0") as c, \
            distributed.Client(c) as cl:
        yield cl


_LOCAL: dict = {}


def _local(structure, files, method, **kw):
    """The unchanged single-process path: every log loaded by the CLI's load_logs, then identify() (cached)."""
    key = (tuple(files), method, tuple(sorted(kw.items())))
    if key not in _LOCAL:
        _LOCAL[key] = identify(structure, load_logs(files, structure.robot, None, None, None, None, 1), method=method, **kw)
    return _LOCAL[key]


# ---- paths --------------------------------------------------------------------------------


def test_glob_is_recursive_sorted_and_a_pattern_matching_nothing_is_a_typed_error(fleet, tmp_path):
    d, files = fleet
    assert len(files) == 4 and files == sorted(files)
    assert {Path(f).parent.name for f in files} == {"robot_0", "robot_1"}  # '**' went into sub-directories
    assert expand_paths([files[1], files[0]]) == [files[1], files[0]]  # plain paths kept as given
    with pytest.raises(DataError, match=r"nothing/\*\*/\*\.parquet.*matches no file"):
        expand_paths([tmp_path / "nothing" / "**" / "*.parquet"])


# ---- same result as the local path -----------------------------------------------------------


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_dask_identification_equals_local_path(fleet, structure, client, method):
    _, files = fleet
    local = _local(structure, files, method)
    dask = identify_files(structure, files, client=client, method=method)
    assert _rel(dask.base_values, local.base_values) < TOL_PRESENTED
    assert _rel(dask.parameters, local.parameters) < TOL_PRESENTED
    assert dask.diagnostics["n_samples"] == local.diagnostics["n_samples"] == 12_000
    assert dask.settings["files_used"] == 4 and dask.settings["skipped_files"] == []
    s_d, s_l = dask.diagnostics["residual_sigma"], local.diagnostics["residual_sigma"]
    # residual σ_r² = c_r − 2b_rᵀπ + πᵀA_rπ cancels digits (by c_r / RSS_r ≈ 10²) in both paths
    assert max(abs(s_d[j] - s_l[j]) / s_l[j] for j in s_l) < 1e-8


def test_compress_with_client_equals_compress_of_loaded_logs(fleet, structure, client):
    _, files = fleet
    ne_local = compress(structure, load_logs(files, structure.robot, None, None, None, None, 1))
    ne_dask = compress(structure, files, client=client)
    assert ne_dask.n_samples == ne_local.n_samples
    for k in ("A", "b", "c", "y_min", "y_max", "y_sum"):
        np.testing.assert_allclose(getattr(ne_dask, k), getattr(ne_local, k), rtol=1e-12, atol=1e-12 * np.abs(ne_local.A).max())
    with pytest.raises(DataError, match="pass file paths"):  # arrays never travel
        compress(structure, load_logs(files[:1], structure.robot, None, None, None, None, 1), client=client)


def test_compress_of_file_paths_without_a_client_runs_in_this_process(fleet, structure):
    """client=None with paths or a glob (docs/fleet.md's snippet): the same sums as the loaded logs,
    read in this process; items that are neither trajectories nor paths are a typed error."""
    d, files = fleet
    ne_local = compress(structure, load_logs(files, structure.robot, None, None, None, None, 1))
    ne_glob = compress(structure, [str(d / "**" / "*.parquet")], client=None)
    assert ne_glob.n_samples == ne_local.n_samples == 12_000
    np.testing.assert_allclose(ne_glob.A, ne_local.A, rtol=1e-12, atol=1e-12 * np.abs(ne_local.A).max())
    np.testing.assert_allclose(ne_glob.b, ne_local.b, rtol=1e-12, atol=1e-12 * np.abs(ne_local.b).max())
    for bad, what in (([{"q": 1}], "got dict"), (3, "got int")):
        with pytest.raises(DataError, match=what):
            compress(structure, bad)


@pytest.mark.parametrize("period", [2.0, None])
def test_cross_validation_folds_equal_the_local_split(fleet, structure, client, period):
    """LMI γ='auto' folds: phase blocks of a period (per file, from its first sample), or contiguous blocks over all files."""
    _, files = fleet
    trajs = load_logs(files, structure.robot, None, None, None, None, 1)
    local = split_folds(structure, trajs, 5, 2048, period)
    got = compress_files(structure, files, client=client, n_folds=5, period=period)
    assert got.period == period
    assert len(got.folds) == 5
    for a, b in zip(got.folds, local):
        assert a.n_samples == b.n_samples
        np.testing.assert_allclose(a.A, b.A, rtol=1e-12, atol=1e-12 * np.abs(b.A).max())
    np.testing.assert_allclose(got.equations.A, sum(f.A for f in local), rtol=1e-12, atol=1e-12 * np.abs(local[0].A).max())


@pytest.mark.slow
@pytest.mark.parametrize("gamma", [1e-3, "auto"])
def test_lmi_on_dask_equals_local(fleet, structure, client, gamma):
    _, files = fleet
    local = _local(structure, files, "lmi", gamma=gamma)
    dask = identify_files(structure, files, client=client, method="lmi", gamma=gamma)
    assert dask.diagnostics["gamma"] == local.diagnostics["gamma"]
    assert _rel(dask.parameters, local.parameters) < TOL_PRESENTED


# ---- bad files, retries, dead workers --------------------------------------------------------


@pytest.fixture()
def with_corrupt(fleet, tmp_path):
    _, files = fleet
    bad = tmp_path / "robot_9" / "log_corrupt.parquet"
    bad.parent.mkdir()
    bad.write_bytes(b"PAR1 this is not a parquet file")
    return files[:2] + [str(bad)] + files[2:], str(bad)


def test_corrupt_file_fails_with_typed_error_naming_it(with_corrupt, structure, client):
    files, bad = with_corrupt
    with pytest.raises(DataError, match=r"log_corrupt\.parquet.*not a readable Parquet"):
        identify_files(structure, files, client=client)


def test_skip_bad_skips_and_reports_the_file_and_equals_local_on_the_rest(with_corrupt, fleet, structure, client):
    files, bad = with_corrupt
    res = identify_files(structure, files, client=client, skip_bad=True)
    (entry,) = res.settings["skipped_files"]
    assert entry["file"] == bad and "not a readable Parquet" in entry["error"]
    assert res.settings["files_used"] == 4
    assert _rel(res.base_values, _local(structure, fleet[1], "ols").base_values) < TOL_PRESENTED
    with pytest.raises(DataError, match="every file was skipped"):
        compress_files(structure, [bad], client=client, skip_bad=True)
    # the cross-validation folds (two passes) skip it too, and cut the other files as the local path does
    got = compress_files(structure, files, client=client, skip_bad=True, n_folds=5, period=None)
    assert [f for f, _ in got.skipped] == [bad] and got.files == fleet[1]
    local = split_folds(structure, load_logs(fleet[1], structure.robot, None, None, None, None, 1), 5, 2048, None)
    for a, b in zip(got.folds, local):
        np.testing.assert_allclose(a.A, b.A, rtol=1e-12, atol=1e-12 * np.abs(b.A).max())


@dataclass(frozen=True)
class FlakyReader(LogReader):
    """Raises an (untyped) OSError on the first attempt at ``victim``, like a network filesystem hiccup."""

    marker: str = ""
    victim: str = ""

    def __call__(self, path, robot):
        if path == self.victim and not os.path.exists(self.marker):
            Path(self.marker).touch()
            raise OSError("transient read failure")
        return super().__call__(path, robot)


def test_a_task_that_raises_is_retried_by_dask(fleet, structure, client, tmp_path):
    _, files = fleet
    reader = FlakyReader(marker=str(tmp_path / "failed_once"), victim=files[2])
    ne = compress_files(structure, files, client=client, reader=reader, retries=1).equations
    assert Path(reader.marker).exists()
    ref = compress_files(structure, files, client=client).equations
    np.testing.assert_array_equal(ne.A, ref.A)  # same tasks, same tree: bit-identical
    reader = FlakyReader(marker=str(tmp_path / "failed_again"), victim=files[2])
    with pytest.raises(DistributedError, match=Path(files[2]).name + r".*after 0 retries.*transient read failure"):
        compress_files(structure, files, client=client, reader=reader, retries=0)


@dataclass(frozen=True)
class KillOnceReader(LogReader):
    """Kills its worker process (os._exit) the first time it reads ``victim``."""

    marker: str = ""
    victim: str = ""

    def __call__(self, path, robot):
        if path == self.victim and not os.path.exists(self.marker):
            Path(self.marker).touch()
            os._exit(1)
        return super().__call__(path, robot)


def test_worker_killed_mid_run_gives_the_same_result(fleet, structure, tmp_path, monkeypatch):
    _, files = fleet
    here = str(Path(__file__).parent)  # worker processes must import this module to unpickle the reader
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([here, os.environ.get("PYTHONPATH", "")]))
    reader = KillOnceReader(marker=str(tmp_path / "killed"), victim=files[1])
    local = _local(structure, files, "ols")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  silence_logs=50) as c, distributed.Client(c) as cl:
        pids = set(cl.run(os.getpid).values())
        res = identify_files(structure, files, client=cl, reader=reader)
        cl.wait_for_workers(2, timeout=30)
        after = set(cl.run(os.getpid).values())
    assert Path(reader.marker).exists()  # the worker did die while reading files[1] ...
    assert after != pids  # ... and the nanny replaced it
    assert res.settings["files_used"] == 4
    assert _rel(res.base_values, local.base_values) < TOL_PRESENTED


# ---- worker-side structure cache and connection errors -------------------------------------------


def test_structure_travels_once_and_is_unpickled_once_per_thread(structure):
    m = PickledModel.of(structure)
    assert len(m.blob) < 2**20  # a pickled Panda structure, not data
    a, b = worker_structure(m), worker_structure(m)
    assert a is b and a is not structure and a.n_params == structure.n_params
    other = []
    t = threading.Thread(target=lambda: other.append(worker_structure(m)))
    t.start()
    t.join()
    assert other[0] is not a  # Pinocchio Data is per-thread scratch space


def test_unreachable_scheduler_is_a_typed_error():
    with pytest.raises(DistributedError, match="tcp://127.0.0.1:9.*cannot reach"):
        with connect("tcp://127.0.0.1:9", timeout=1):
            pass


# ---- CLI ----------------------------------------------------------------------------------------

runner = CliRunner()


def _cli(args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def tcp_cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp",
                                  dashboard_address=":0") as c:
        yield c.scheduler_address


def _params(out):
    doc = json.loads((out / "result.json").read_text())
    return doc, np.array(list(doc["parameters"].values()))


def test_cli_identify_on_a_cluster_equals_local_and_expands_the_glob(fleet, tcp_cluster, tmp_path):
    d, _ = fleet
    pattern = str(d / "**" / "*.parquet")
    r1 = _cli(["identify", *ROBOT, "--data", pattern, "--method", "wls", "--out", tmp_path / "local"])
    assert r1.exit_code == 0, r1.output
    r2 = _cli(["identify", *ROBOT, "--data", pattern, "--method", "wls", "--scheduler", tcp_cluster,
               "--workers", 2, "--out", tmp_path / "dask"])
    assert r2.exit_code == 0, r2.output
    (doc_l, p_l), (doc_d, p_d) = _params(tmp_path / "local"), _params(tmp_path / "dask")
    assert _rel(p_d, p_l) < TOL_PRESENTED
    assert doc_d["settings"]["data"] == doc_l["settings"]["data"] and len(doc_d["settings"]["data"]) == 4
    assert doc_d["settings"]["scheduler"] == tcp_cluster and doc_d["settings"]["skipped_files"] == []
    assert (tmp_path / "dask" / "torques.png").exists()


def test_cli_bad_file_fails_without_output_or_is_skipped_and_listed(with_corrupt, tcp_cluster, tmp_path):
    files, bad = with_corrupt
    data = [a for f in files for a in ("--data", f)]
    out = tmp_path / "run"
    r = _cli(["identify", *ROBOT, *data, "--scheduler", tcp_cluster, "--out", out])
    assert r.exit_code == 2 and "log_corrupt.parquet" in r.output and not out.exists()
    r = _cli(["identify", *ROBOT, *data, "--scheduler", tcp_cluster, "--skip-bad", "--out", out])
    assert r.exit_code == 0, r.output
    assert "1 file(s) skipped" in r.output
    doc, _ = _params(out)
    assert [e["file"] for e in doc["settings"]["skipped_files"]] == [bad]
    assert bad not in doc["settings"]["data"] and len(doc["settings"]["data"]) == 4


@dataclass(frozen=True)
class CountingReader(LogReader):
    """Appends the path to ``log`` at each read (how many times a task ran)."""

    log: str = ""

    def __call__(self, path, robot):
        with open(self.log, "a") as f:
            f.write(f"{path}\n")
        return super().__call__(path, robot)


def test_a_file_that_cannot_be_used_fails_once_as_its_typed_error_with_nothing_logged(fleet, client, tmp_path, caplog):
    """Regression (issue 24, quickstart 6): without the finger locks every file failed on the workers,
    was retried, and Dask logged each attempt with a traceback. The typed error now returns as a
    value: raised once on the client, naming the file and the fix, no retry, no log line."""
    from sensorless import load_robot

    _, files = fleet
    unlocked = ModelStructure(load_robot("panda"), joint_terms=("fv",))
    reader = CountingReader(log=str(tmp_path / "reads.txt"))
    with caplog.at_level(logging.INFO), pytest.raises(JointNameError) as exc:
        compress_files(unlocked, files, client=client, reader=reader, retries=2)
    msg = str(exc.value)
    assert any(f in msg for f in files) and "`lock_joints=['panda_finger_joint1', 'panda_finger_joint2']`" in msg
    reads = (tmp_path / "reads.txt").read_text().split()
    assert len(reads) == len(set(reads)) <= len(files)  # no file read twice: no retry of a typed error
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING and r.name.startswith("distributed")]


def test_cli_missing_lock_on_a_cluster_is_the_single_process_line(fleet, tcp_cluster, tmp_path):
    """Quickstart 6 as printed (no --lock for the fingers) on a cluster: the same one line as the
    single-process run, in flag language; with the friction law fitted on the workers too (the client
    reads no log), one error line naming a file and the --lock fix, no traceback."""
    d, _ = fleet
    pattern = str(d / "**" / "*.parquet")
    base = ["identify", "--robot", "panda", "--data", pattern, "--method", "ols", "--no-plot"]
    lines = {}
    for name, extra in (("single", []), ("dask", ["--scheduler", tcp_cluster, "--workers", 2]),
                        ("workers", ["--scheduler", tcp_cluster, "--joint-terms", "fv,fc,offset",
                                     "--coulomb-smoothing", "0.01"])):
        r = _cli([*base, *extra, "--out", tmp_path / name])
        text = r.output
        errors = [ln for ln in text.splitlines() if ln.startswith("error:")]
        assert r.exit_code == 2 and len(errors) == 1 and "Traceback" not in text and not (tmp_path / name).exists(), text
        assert len([ln for ln in text.splitlines() if ln.strip()]) <= 2, text  # at most the "Dask: ..." line besides
        assert "--lock panda_finger_joint1 --lock panda_finger_joint2" in errors[0] and "lock_joints" not in text
        lines[name] = errors[0]
    assert lines["dask"] == lines["single"]
    assert ".parquet: missing joint(s)" in lines["workers"]


def test_cli_glob_matching_nothing_fails_naming_the_pattern(tmp_path):
    out = tmp_path / "run"
    r = _cli(["identify", *ROBOT, "--data", str(tmp_path / "none" / "**" / "*.parquet"), "--out", out])
    assert r.exit_code == 2 and "matches no file" in r.output and "none/**/*.parquet" in r.output and not out.exists()
    r = _cli(["identify", *ROBOT, "--data", str(tmp_path / "x.parquet"), "--workers", 2, "--out", out])
    assert r.exit_code == 2 and "--workers needs --scheduler" in r.output and not out.exists()


def test_cli_auto_coulomb_smoothing_on_a_cluster_equals_local(fleet, tcp_cluster, tmp_path):
    """Regression: with --scheduler, --coulomb-smoothing auto silently fell back to sgn(v), and the
    Stribeck vs was not searched. ε and the vs candidates are now measured on the first training log
    in both modes and vs is chosen on the summed equations, so two noisy logs give the same ε, vs
    and parameters locally and on a cluster."""
    import pandas as pd

    d, files = fleet
    rng = np.random.default_rng(0)
    noisy = []
    for k, f in enumerate(files[:2]):
        df = pd.read_parquet(f)
        for c in [c for c in df.columns if c.startswith("q_")]:  # encoder noise: v (from q) is noisy
            df[c] = df[c] + rng.normal(scale=(1 + k) * 1e-4, size=len(df))
        noisy.append(tmp_path / f"noisy{k}.parquet")
        df.to_parquet(noisy[-1])
    r1 = _cli(["identify", *ROBOT, "--data", *noisy, "--method", "wls", "--no-plot", "--out", tmp_path / "local"])
    assert r1.exit_code == 0, r1.output
    r2 = _cli(["identify", *ROBOT, "--data", *noisy, "--method", "wls", "--no-plot", "--scheduler", tcp_cluster,
               "--out", tmp_path / "dask"])
    assert r2.exit_code == 0, r2.output
    (doc_l, p_l), (doc_d, p_d) = _params(tmp_path / "local"), _params(tmp_path / "dask")
    fl, fd = doc_l["settings"]["friction"], doc_d["settings"]["friction"]
    assert min(fl["coulomb_smoothing"].values()) > 0 and fd["coulomb_smoothing"] == fl["coulomb_smoothing"]
    assert fl["coulomb_smoothing_mode"] == fd["coulomb_smoothing_mode"] == "auto"
    # the default model has a Stribeck term: vs (or none, for this friction without a Stribeck effect) is
    # chosen on the summed equations, every joint, the same in both modes
    assert set(fl["stribeck_search"]) == set(fl["coulomb_smoothing"]) and fd["stribeck_grid"] == fl["stribeck_grid"]
    assert {j: r["vs"] for j, r in fd["stribeck_search"].items()} == {j: r["vs"] for j, r in fl["stribeck_search"].items()}
    assert fd["stribeck_velocity"] == fl["stribeck_velocity"] and ({j: set(t) for j, t in doc_d["joint_terms"].items()}
                                                              == {j: set(t) for j, t in doc_l["joint_terms"].items()})
    assert _rel(p_d, p_l) < TOL_PRESENTED


def test_cli_wrench_mode_with_imu_frame_on_a_cluster_equals_local(tcp_cluster, tmp_path, solo12):
    """Floating base on Dask: contact wrenches measured, base acceleration from an accelerometer
    read in a model frame on the workers, contact rows chosen from the first log (no torques:
    base rows). Used to be refused ('--scheduler does not support ...')."""
    from sensorless.data import write_npz
    from sensorless.data.imu import gravity_in_base
    from sensorless.testing import perturbed_truth
    from sensorless_studies.simulation import wrench_log

    feet = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
    truth = perturbed_truth(solo12, rng=6)
    paths = []
    for seed in (4, 5):
        lg = wrench_log(truth.robot, feet, duration=3.0, dims=3, seed=seed, base_amplitude=(0.2, 0.4))
        v, w = lg.base_v[:, :3], lg.base_v[:, 3:]
        imu = lg.base_a[:, :3] + np.cross(w, v) - gravity_in_base(lg.base_q, 9.81)
        paths.append(write_npz(lg.with_(base_a=None, extras={**lg.extras, "imu_acc": imu}), tmp_path / f"imu{seed}.npz"))
    base = ["identify", "--robot", "solo12", "--data", *map(str, paths), "--contact-frames", ",".join(feet),
            "--contact-mode", "wrench", "--joint-terms", "", "--imu-frame", "base_link", "--method", "ols", "--no-plot"]
    r1 = _cli([*base, "--out", tmp_path / "local"])
    assert r1.exit_code == 0, r1.output
    r2 = _cli([*base, "--scheduler", tcp_cluster, "--out", tmp_path / "dask"])
    assert r2.exit_code == 0, r2.output
    assert "contact rows: base" in r2.output
    (doc_l, p_l), (doc_d, p_d) = _params(tmp_path / "local"), _params(tmp_path / "dask")
    assert _rel(p_d, p_l) < TOL_PRESENTED
    m_true = float(truth.robot.inertial_parameters().reshape(-1, 10)[:, 0].sum())
    assert doc_d["mass_properties"]["total_mass"] == pytest.approx(m_true, rel=2e-3)
