"""sensorless.run.logs: a run's logs read with their trim windows, unreadable files skipped only when
asked (and reported), and what result.json records about the logs."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.data import write_npz
from sensorless.data.trims import LogTrims
from sensorless.errors import SensorlessError
from sensorless.excitation import random_fourier
from sensorless.run.logs import first_training_log, load_logs, load_training, log_settings, preprocessing_settings
from sensorless.testing import perturbed_truth, synthetic_trajectory

PREP = dict(columns=None, rate=None, lowpass=None, savgol_window=None, decimate=1)


@pytest.fixture(scope="module")
def logs(tmp_path_factory, ur5):
    """Two good 2 s UR5 logs at 100 Hz and a file that is no log."""
    d = tmp_path_factory.mktemp("logs")
    truth = perturbed_truth(ur5, rng=2)
    for name, seed in (("a", 41), ("b", 43)):
        traj = synthetic_trajectory(truth, random_fourier(ur5, rng=seed).sample(100, 2.0), noise_std=0.05, rng=seed)
        write_npz(traj, d / f"{name}.npz")
    (d / "bad.npz").write_bytes(b"not a log")
    return d / "a.npz", d / "b.npz", d / "bad.npz"


def test_each_log_gets_its_own_trim_window(ur5, logs):
    a, b, _ = logs
    counted = []
    whole = load_logs([a, b], ur5, **PREP)
    trims = LogTrims.parse(["0.5:1.5", "b.npz=0:1"])
    ta, tb = load_logs([a, b], ur5, **PREP, trim=trims, progress=counted.append)
    assert counted == [1, 1]
    assert [len(t) for t in whole] == [200, 200]
    assert ta.t[0] >= whole[0].t[0] + 0.5 - 1e-9 and ta.t[-1] <= whole[0].t[0] + 1.5 + 1e-9
    assert tb.t[-1] <= whole[1].t[0] + 1.0 + 1e-9 and len(ta) > len(tb) * 0.9
    i = int(np.searchsorted(whole[0].t, ta.t[0]))
    assert np.array_equal(ta.q, whole[0].q[i:i + len(ta)])  # a window of the same samples
    s = log_settings(trims, [a, b], [ta, tb])
    assert s["trims"] == {str(a): "0.5:1.5", str(b): "0:1"} and s["rows_dropped"] == {}


def test_a_bad_file_fails_the_run_unless_skipped(ur5, logs):
    a, b, bad = logs
    with pytest.raises(SensorlessError, match="bad.npz"):
        load_training([a, bad, b], ur5, PREP, skip_bad=False)
    train, used, skipped = load_training([a, bad, b], ur5, PREP, skip_bad=True)
    assert len(train) == 2 and used == [a, b]
    assert [f for f, _ in skipped] == [str(bad)] and str(bad) in skipped[0][1]
    with pytest.raises(SensorlessError, match=r"every `logs\.data` file was skipped"):
        load_training([bad], ur5, PREP, skip_bad=True)


def test_the_first_training_log_on_this_machine(ur5, logs, tmp_path):
    a, b, bad = logs
    [first] = first_training_log([a, b], ur5, PREP)
    assert np.array_equal(first.q, load_logs([a], ur5, **PREP)[0].q)
    assert first_training_log([tmp_path / "elsewhere.npz", a], ur5, PREP) == []  # a worker's file
    with pytest.raises(SensorlessError, match="bad.npz"):
        first_training_log([bad, a], ur5, PREP)
    assert first_training_log([bad, a], ur5, PREP, skip_bad=True) == []


def test_preprocessing_settings_record_the_options(ur5, logs):
    a, b, _ = logs
    train = load_logs([a, b], ur5, **PREP)
    s = preprocessing_settings(train, columns=None, gains=None, rate=None, trim=None, resample="auto", lowpass=5.0,
                               savgol_window=None, velocity="logged", decimate=1, max_gap=None, paths=[a, b])
    assert (s["lowpass"], s["resample"], s["velocity"], s["angle_unit"]) == (5.0, "auto", "logged", "rad")
    assert s["trim"] is None and s["trims"] == {str(a): None, str(b): None} and s["skip_bad_rows"] is False
