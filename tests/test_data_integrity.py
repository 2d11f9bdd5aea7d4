"""Duplicated and corrupted logs (issue #41): the same log twice, shuffled torque rows, periodic zero samples,
Parquet pages failing their checksums."""

from __future__ import annotations

import os
import shutil
import warnings

import numpy as np
import pytest

from sensorless.data import Trajectory, write_npz
from sensorless.data.integrity import check_integrity, duplicate_logs, unique_logs
from sensorless.data.prepare import load_log
from sensorless.errors import DataError, DataWarning
from sensorless.excitation import random_fourier
from sensorless.regressor.distributed import expand_paths
from sensorless.robot import load_robot
from sensorless.testing import (RealArtefacts, one_joint_at_a_time, perturbed_truth, synthetic_trajectory,
                                with_real_artefacts)

REAL = RealArtefacts(q_step=2 * np.pi / 2**17, decimals=4, gain_error=0.05, holding=0.5, stiffness=2e4, jitter=2e-4)


@pytest.fixture(scope="module")
def logs():
    """A UR5 log (Fourier excitation, 100 Hz, 20 s) and a one-joint-at-a-time log, both with realistic
    artefacts (encoder quantum, 4 decimals, gain error, holding torque at rest, flexibility, stamp jitter)."""
    robot = load_robot("ur5")
    truth = perturbed_truth(robot, rng=3)
    motion = random_fourier(robot, rng=4).sample(100, 20.0)
    fourier = with_real_artefacts(synthetic_trajectory(truth, motion, noise_std=0.2, rng=5), REAL, rng=6)
    t = np.arange(2000) / 100.0
    q, v, a = one_joint_at_a_time(t, np.zeros(6), amplitude=0.8, period=4.0)
    one = with_real_artefacts(synthetic_trajectory(truth, Trajectory(t=t, q=q, v=v, a=a, joint_names=tuple(robot.joint_names)),
                                                   noise_std=0.2, rng=7), REAL, rng=8)
    return fourier, one


def test_sound_logs_pass(logs):
    for traj in logs:
        check_integrity(traj)


def test_shuffled_torque_rows_refused(logs):
    """Reproducer: shuffled torque rows were fitted without a word."""
    for traj in logs:
        perm = np.random.default_rng(0).permutation(len(traj))
        with pytest.raises(DataError, match="torque rows look shuffled"):
            check_integrity(traj.with_(tau=traj.tau[perm]))


@pytest.mark.parametrize("k", [2, 3, 7])
def test_periodic_zero_samples_refused(logs, k):
    """Reproducer: every other torque sample zero was accepted."""
    traj = logs[0]
    tau = traj.tau.copy()
    tau[1::k, 2] = 0.0
    with pytest.raises(DataError, match=rf"tau\[elbow_joint\] is exactly 0 on every {k}(nd|rd|th) sample"):
        check_integrity(traj.with_(tau=tau))


def test_same_log_twice_counted_once(logs, tmp_path):
    """Reproducer: the same log fed twice (symlink, hard link, a copy, a glob through `latest -> ..`, 41
    copies) shrank the uncertainties up to 6.4× without a warning. Each is read once, with a warning."""
    d = tmp_path / "logs"
    d.mkdir()
    a = d / "a.npz"
    write_npz(logs[0], a)
    write_npz(logs[1], d / "b.npz")
    (d / "link.npz").symlink_to(a)
    os.link(a, d / "hard.npz")
    shutil.copy(a, d / "copy.npz")
    (d / "latest").symlink_to("..")
    paths = [a, d / "b.npz", d / "link.npz", d / "hard.npz", d / "copy.npz", d / "latest" / "logs" / "a.npz"]
    how = {i: h for i, _, h in duplicate_logs(paths)}
    assert how == {2: "the same file", 3: "a hard link to it", 4: "an identical copy", 5: "the same file"}
    with pytest.warns(DataWarning, match=r"the same log was given more than once .*link\.npz is the same file"):
        assert unique_logs(paths) == [a, d / "b.npz"]
    globbed = [str(p) for p in expand_paths([d / "*.npz", d / "latest" / "logs" / "*.npz"])]
    with pytest.warns(DataWarning):
        assert sorted(map(os.path.basename, unique_logs(globbed))) == ["a.npz", "b.npz"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert unique_logs([a, d / "b.npz"]) == [a, d / "b.npz"]


def test_load_log_refuses_corrupted_rows(logs, tmp_path):
    traj = logs[0]
    tau = traj.tau.copy()
    tau[::2, 0] = 0.0
    write_npz(traj.with_(tau=tau), tmp_path / "z.npz")
    with pytest.raises(DataError, match=r"z\.npz.*tau\[shoulder_pan_joint\] is exactly 0 on every 2nd sample"):
        load_log(tmp_path / "z.npz", load_robot("ur5"), None, None, None, None, None)


def test_parquet_page_checksum_failure_refused(logs, tmp_path):
    """Reproducer: 1000 zeroed bytes in a Parquet file set 126 samples to 0. Pages written with CRCs are
    verified: the corrupt page is refused by the whole-log and the chunked readers."""
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    from sensorless.data import read_trajectory
    from sensorless.data.chunks import open_chunked

    traj = logs[0]
    cols = {"t": traj.t}
    for f in ("q", "v", "tau"):
        for j, n in enumerate(traj.joint_names):
            cols[f"{f}_{n}"] = getattr(traj, f)[:, j]
    path = tmp_path / "log.parquet"
    pq.write_table(pa.Table.from_pandas(pd.DataFrame(cols)), path, compression="none", write_page_checksum=True)
    assert read_trajectory(path).q.shape == traj.q.shape
    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2 : len(raw) // 2 + 1000] = bytes(1000)
    path.write_bytes(bytes(raw))
    with pytest.raises(DataError, match="CRC checksum verification failed"):
        read_trajectory(path)
    chunked = open_chunked(path, traj.joint_names)
    with pytest.raises(DataError, match="CRC checksum verification failed"):
        for _ in chunked.chunks(["t", "q", "v", "tau"], 500):
            pass


def test_real_logs_pass():
    """The KUKA and dVRK PSM logs (real robots, their noise and quantisation) raise no integrity error."""
    from conftest import REALDATA

    from sensorless.data import read_trajectory
    from sensorless.data.prepare import parse_columns

    kuka = sorted((REALDATA / "kuka_lwr4_flobaroid" / "data" / "KUKA" / "HW").glob("measurements_*.npz"))
    psm = sorted((REALDATA / "dvrk_psm_wpi" / "data" / "psm" / "measured_trajectory").glob("*_results.csv"))
    if not kuka and not psm:
        pytest.skip("../shared/realdata is absent")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        logs = [read_trajectory(p) for p in kuka] + [
            read_trajectory(p, columns=parse_columns("q=0:7;v=7:14;tau=14:21"), rate=200,
                            joint_names=[f"j{i}" for i in range(7)]) for p in psm]
    for traj in logs:
        check_integrity(traj)
