"""One name table for every reader (sensorless.data.names): each common name of a signal is
recognised in NPZ, HDF5, MATLAB, CSV/Parquet headers and per-signal file names, a logged
velocity/acceleration is used (or replaced with --velocity from-q), and what no field uses is
named in one warning."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from sensorless.data import read_trajectory
from sensorless.data.names import FIELD_NAMES, field_of
from sensorless.errors import DataWarning

NAMES = ("j1", "j2")
N = 120


def _signals(seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(N) / 100.0
    q = 0.5 * np.sin(t[:, None] * [1.0, 1.7])
    w = np.array([1.0, 1.7])
    noise = lambda: 1e-3 * rng.normal(size=(N, 2))  # noqa: E731
    # a consistent log (v = dq/dt, smooth torques): the readers' integrity checks pass it
    return {"t": t, "q": q, "v": 0.5 * w * np.cos(t[:, None] * w) + noise(),
            "a": -0.5 * w**2 * np.sin(t[:, None] * w) + noise(),
            "tau": np.cos(t[:, None] * w + 0.3) + noise(), "current": np.sin(t[:, None] * w + 0.7) + noise()}


def _write(fmt: str, path, named: dict[str, np.ndarray]):
    """``named``: stored name -> array (time 1-D, signals N × 2)."""
    if fmt == "npz":
        np.savez(path / "log.npz", **named)
        return path / "log.npz"
    if fmt == "h5":
        import h5py

        with h5py.File(path / "log.h5", "w") as f:
            for k, v in named.items():
                f[f"robot/{k}"] = v  # in a group: the last path component is the name
        return path / "log.h5"
    if fmt == "mat":
        from scipy.io import savemat

        savemat(path / "log.mat", {"data": named})
        return path / "log.mat"
    if fmt in ("csv", "parquet"):
        cols = {}
        for k, v in named.items():
            if v.ndim == 1:
                cols[k] = v
            else:
                cols.update({f"{k}_{j}": v[:, i] for i, j in enumerate(NAMES)})
        df = pd.DataFrame(cols)
        out = path / f"log.{fmt}"
        df.to_csv(out, index=False, float_format="%.17g") if fmt == "csv" else df.to_parquet(out)
        return out
    folder = path / "run"  # per-signal files: name.dat, first column the time
    folder.mkdir()
    t = named.pop(next(k for k in named if field_of(k) == "t"))
    for k, v in named.items():
        np.savetxt(folder / f"{k}.dat", np.column_stack([t, v]), fmt="%.17g", header="t " + " ".join(NAMES),
                   comments="")
    return folder


FORMATS = ("npz", "h5", "mat", "csv", "parquet", "dat")
SPELLINGS = [  # (time, velocity, acceleration, torque, current) names as labs store them
    ("t", "dq", "ddq", "tau", "current"),
    ("time", "qd", "qdd", "effort", "i"),
    ("stamp", "qdot", "qddot", "torque", "cur"),
]


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("spelling", SPELLINGS, ids=lambda s: "-".join(s))
def test_common_names_are_recognised_by_every_reader(tmp_path, fmt, spelling):
    sig = _signals()
    t_name, v_name, a_name, tau_name, i_name = spelling
    named = {t_name: sig["t"], "q": sig["q"], v_name: sig["v"], a_name: sig["a"], tau_name: sig["tau"],
             i_name: sig["current"], "temperature": np.ones((N, 2))}
    path = _write(fmt, tmp_path, named)
    with pytest.warns(DataWarning, match=r"not used: '(robot/|data/)?temperature") as rec:
        tr = read_trajectory(path, joint_names=NAMES)
    assert sum("not used" in str(w.message) for w in rec) == 1
    for f in ("t", "q", "v", "a", "tau"):
        np.testing.assert_array_equal(getattr(tr, f), sig[f], err_msg=f)
    np.testing.assert_array_equal(tr.extras["current"], sig["current"])


def test_logged_velocity_is_kept_unless_velocity_from_q(tmp_path):
    from sensorless.data.prepare import load_log

    sig = _signals()
    np.savez(tmp_path / "log.npz", t=sig["t"], q=sig["q"], dq=sig["v"], ddq=sig["a"], tau=sig["tau"])
    kept = load_log(tmp_path / "log.npz", None, None, None, None, None, 1, rest="off")
    assert kept.provenance["v"] == "logged" and kept.provenance["a"] == "logged"
    np.testing.assert_array_equal(kept.v, sig["v"])
    np.testing.assert_array_equal(kept.a, sig["a"])
    derived = load_log(tmp_path / "log.npz", None, None, None, None, None, 1, velocity="from-q", rest="off")
    assert derived.provenance["v"].startswith("derived") and not np.allclose(derived.v, sig["v"])


def test_a_log_using_only_known_names_warns_nothing(tmp_path):
    from sensorless.data import Trajectory, write_npz

    sig = _signals()
    write_npz(Trajectory(t=sig["t"], q=sig["q"], v=sig["v"], a=sig["a"], tau=sig["tau"], joint_names=NAMES),
              tmp_path / "w.npz")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        read_trajectory(tmp_path / "w.npz")


def test_one_table_for_fields_time_units_and_cli_choices():
    from sensorless.cli import options
    from sensorless.data.readers import FIELDS
    from sensorless.data.tabular import FIELD_WORDS, TIME_COLUMNS
    from sensorless.data.angles import ANGLE_UNITS
    from sensorless.data.timebase import TIME_UNITS
    from sensorless.identification import artifact_schema

    assert FIELDS == tuple(FIELD_NAMES)
    assert all(FIELD_WORDS[f] == FIELD_NAMES[f] for f in FIELD_WORDS) and set(FIELD_NAMES["t"]) <= set(TIME_COLUMNS)
    assert tuple(options.TimeUnit) == TIME_UNITS == artifact_schema.TIME_UNITS
    assert tuple(options.AngleUnit) == ANGLE_UNITS == artifact_schema.ANGLE_UNITS
    names = [n.lower() for names in FIELD_NAMES.values() for n in names]
    assert len(names) == len(set(names)), "a name stands for one field"
    assert field_of("jointPositions") == "q" and field_of("dq") == "v" and field_of("Ticks") == "t"
