"""Per-log trim windows (sensorless.data.LogTrims, --trim FILE=WINDOW): matched by path or file name,
a name matching no log or several is an error naming it, and each log is cut to its own window."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.data import LogTrims, TrimWindow
from sensorless.errors import OptionError

LOGS = ["runs/a/unloaded.csv", "runs/a/loaded.csv", "runs/b/loaded.csv"]


def test_a_window_for_every_log_and_one_per_log():
    trims = LogTrims.parse(["1:-1", "unloaded.csv=2.5:", "runs/b/loaded.csv=abs:100:160"])
    got = trims.resolve(LOGS)
    assert [str(w) for w in got] == ["2.5:", "1:-1", "abs:100:160"]
    s = trims.settings(LOGS)
    assert s["trim"] == "1:-1" and s["trims"] == dict(zip(LOGS, ["2.5:", "1:-1", "abs:100:160"]))
    assert LogTrims.parse("0:5").resolve(LOGS) == [TrimWindow(0, 5)] * 3
    assert LogTrims.parse(None).resolve(LOGS) == [None] * 3 and not LogTrims.parse(None)


def test_a_name_matching_no_log_or_several_is_an_error_naming_it():
    with pytest.raises(OptionError, match=r"`trim` nope.csv=...: 'nope.csv' matches none of the logs"):
        LogTrims.parse(["nope.csv=1:2"]).resolve(LOGS)
    with pytest.raises(OptionError, match=r"'loaded.csv' is ambiguous, it matches runs/a/loaded.csv, runs/b/loaded.csv"):
        LogTrims.parse(["loaded.csv=1:2"]).resolve(LOGS)
    assert str(LogTrims.parse(["a/loaded.csv=1:2"]).resolve(LOGS)[1]) == "1:2"  # more of the path: one log
    with pytest.raises(OptionError, match="two windows for every log"):
        LogTrims.parse(["1:2", "3:4"])
    with pytest.raises(OptionError, match=r"`trim` 'unloaded.csv=1-2'.*START:END"):
        LogTrims.parse(["unloaded.csv=1-2"])
    with pytest.raises(OptionError, match="named twice"):
        LogTrims.parse(["unloaded.csv=1:2", "a/unloaded.csv=3:4"]).resolve(LOGS)


def test_each_log_is_cut_to_its_own_window_while_reading(tmp_path, ur5):
    """Two runs written with the same stamps; each log's window is cut before the time checks."""
    import pandas as pd

    from sensorless.run.logs import load_logs

    t = np.arange(500) * 0.01
    for name in ("u.csv", "l.csv"):
        cols = {"time": t, **{f"q_{j}": 0.1 * np.sin(t + k) for k, j in enumerate(ur5.joint_names)},
                **{f"tau_{j}": np.cos(t + k) for k, j in enumerate(ur5.joint_names)}}
        pd.DataFrame(cols).to_csv(tmp_path / name, index=False)
    paths = [tmp_path / "u.csv", tmp_path / "l.csv"]
    u, lo = load_logs(paths, ur5, None, None, None, None, 1, trim=["1:-1", "l.csv=2.5:3.5"])
    assert u.t[0] == pytest.approx(1.0) and u.t[-1] == pytest.approx(3.99)
    assert lo.t[0] == pytest.approx(2.5) and lo.t[-1] == pytest.approx(3.5)
    assert lo.provenance["trim"]["window"] == "2.5:3.5" and u.provenance["trim"]["window"] == "1:-1"


def test_identify_and_predict_take_per_log_windows_and_record_them(tmp_path):
    """identify: one window for every log, another for the held-out log, in result.json; predict
    names its own log; a window naming no log is refused."""
    import json

    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless_studies.simulation.current_arm import drive_gains_for, simulate, truth_model

    robot, truth = truth_model("ur5", 0)
    K = drive_gains_for(robot)
    train, val = tmp_path / "train.csv", tmp_path / "val.csv"
    for path, seed in ((train, 1), (val, 2)):
        simulate(robot, truth, K, seed=seed, motion=6.0, idle_start=1.0, idle_end=1.0, ramp=1.0).to_csv(path, index=False)
    common = ["--robot", "ur5", "--columns", "q=pos_{joint};v=vel_{joint};tau=i_{joint}"]
    gains = ["--gains", ",".join(map(str, K))]
    r = CliRunner().invoke(app, ["identify", *common, *gains, "--data", str(train), "--validate", str(val),
                                 "--method", "ols", "--joint-terms", "fv,fc,offset", "--no-plot", "--trim", "1:-1",
                                 "--trim", "val.csv=2:6", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "m" / "result.json").read_text())
    pre = doc["settings"]["preprocessing"]
    assert pre["trim"] == "1:-1" and pre["trims"] == {str(train): "1:-1", str(val): "2:6"}
    sig = doc["settings"]["signals"]
    assert sig[str(val)]["trim"]["window"] == "2:6" and sig[str(train)]["trim"]["window"] == "1:-1"
    r = CliRunner().invoke(app, ["predict", *common[:2], "--model", str(tmp_path / "m"), "--data", str(val),
                                 "--trim", "val.csv=3:5", "--out", str(tmp_path / "p.npz")])
    assert r.exit_code == 0, r.output
    t = np.load(tmp_path / "p.npz")["t"]
    assert t[-1] - t[0] == pytest.approx(2.0, abs=0.03)
    r = CliRunner().invoke(app, ["predict", *common[:2], "--model", str(tmp_path / "m"), "--data", str(val),
                                 "--trim", "train.csv=3:5", "--out", str(tmp_path / "q.npz")])
    assert r.exit_code == 2 and "--trim train.csv=...: 'train.csv' matches none of the logs" in " ".join(r.output.split())


def test_a_config_file_gives_one_window_as_a_string(tmp_path):
    """run.toml ``trim = "1:-1"`` (one window, not a list) is the window for every log."""
    import json

    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless_studies.simulation.current_arm import drive_gains_for, simulate, truth_model

    robot, truth = truth_model("ur5", 0)
    K = drive_gains_for(robot)
    simulate(robot, truth, K, seed=1, motion=6.0, idle_start=1.0, idle_end=1.0, ramp=1.0).to_csv(
        tmp_path / "train.csv", index=False)
    (tmp_path / "run.toml").write_text('trim = "1:-1"\nmethod = "ols"\njoint_terms = "fv,fc,offset"\nplot = false\n')
    r = CliRunner().invoke(app, ["identify", "--config", str(tmp_path / "run.toml"), "--robot", "ur5", "--columns",
                                 "q=pos_{joint};v=vel_{joint};tau=i_{joint}", "--gains", ",".join(map(str, K)),
                                 "--data", str(tmp_path / "train.csv"), "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    pre = json.loads((tmp_path / "m" / "result.json").read_text())["settings"]["preprocessing"]
    assert pre["trim"] == "1:-1" and pre["trims"] == {str(tmp_path / "train.csv"): "1:-1"}


def test_a_window_does_not_hide_stamps_running_backwards_in_the_middle(tmp_path):
    """Fuzz class ``formats``: stamps reset to 0 for 3 rows mid-log fell outside the window and were
    dropped silently (the gap then interpolated by --resample auto); the corrupt prefix is still cut."""
    import warnings

    from sensorless.data import read_trajectory
    from sensorless.errors import TimestampError

    n = 300
    t = 1.0 + np.arange(n) / 100.0
    q = np.column_stack([np.sin(t), np.cos(t)])
    tt = t.copy()
    tt[150:153] = 0.0  # a logger's clock reset mid-log
    tt[:5] = 9.0 + np.arange(5)  # and a corrupt prefix (later than the log)
    path = tmp_path / "run.csv"
    np.savetxt(path, np.column_stack([tt, q]), delimiter=",", header="t,q_a,q_b", comments="", fmt="%.17g")
    with pytest.raises(TimestampError, match=r"run.csv: trim window 'abs:1.1:3.8' .* would leave out 3 sample\(s\) "
                                             r"amid the ones it keeps, first sample 150 \(t\[150\] = 0 s"):
        read_trajectory(path, trim="abs:1.1:3.8")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tr = read_trajectory(path, trim="abs:1.1:2.4")  # a window that ends before the reset: the prefix is cut
    assert len(tr) == 131 and np.array_equal(tr.t, t[10:141]) and np.array_equal(tr.q, q[10:141])
