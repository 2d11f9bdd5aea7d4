"""Issue 41 regressions ("safe as a service"): each reproducer of the outside attack, as a test.

Disclosure (TOML overrides, files only a TOML named, MATLAB cells with HDF5 external storage, escape
sequences), crashes and hangs (FIFOs and devices as logs, a 5000-link URDF, a 2·10⁹-character MATLAB
item, a deeply nested TOML) and internal errors (markup in names, long or undecodable --out names,
extreme resampling). The stream monitor's are in test_realtime_guard.py, the output folder's in
test_io_safe_paths.py, the duplicated and corrupted logs' in test_data_integrity.py.
"""

from __future__ import annotations

import os

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from matlab_writer import CellStr, write_mat73
from sensorless.cli import app
from sensorless.data import read_trajectory, write_npz
from sensorless.errors import DataError, InputError, OptionError, RobotModelError
from sensorless.excitation import random_fourier
from sensorless.robot import load_robot
from sensorless.run.toml import read_run_toml
from sensorless.testing import perturbed_truth, synthetic_trajectory

runner = CliRunner()
SECRET = "hunter2-the-password"


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A small UR5 log, a file with a secret, and a FIFO."""
    d = tmp_path_factory.mktemp("svc")
    robot = load_robot("ur5")
    traj = synthetic_trajectory(perturbed_truth(robot, rng=1), random_fourier(robot, rng=2).sample(100, 10.0),
                                noise_std=0.1, rng=3)
    write_npz(traj, d / "good.npz")
    (d / "secret.txt").write_text(f"user: admin password {SECRET}\nmore\n")
    return d, traj


def _one_line(res) -> str:
    return " ".join(res.output.split())


@pytest.mark.parametrize("key", ["force", "allow_hdf5_external", "accept_implausible", "accept_implausible_gains",
                                 "trust_xacro"])
def test_toml_cannot_give_consent_or_overrides(work, key, tmp_path):
    """Reproducer: a TOML config could set allow_hdf5_external, force and accept_implausible itself."""
    d, _ = work
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'robot = "ur5"\ndata = ["{d / "good.npz"}"]\n{key} = true\n')
    with pytest.raises(OptionError, match="command line only"):
        read_run_toml(cfg)
    res = runner.invoke(app, ["identify", "--config", str(cfg), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "command line only" in _one_line(res) and not (tmp_path / "o").exists()


def test_config_errors_name_their_cause_not_a_missing_option(work, tmp_path):
    """Reproducer: config errors printed `Missing option '--data'` instead of the real cause."""
    d, _ = work
    cases = {"unknown key": ('robot = "ur5"\ndata = ["x.npz"]\nbogus = 1\n', "unknown key(s) bogus"),
             "nested": ("a = " + "[" * 5000 + "]" * 5000 + "\n", "nested too deeply"),
             "syntax": ('robot = "ur5\n', "not a readable TOML file"),
             "consent": ('robot = "ur5"\nforce = true\n', "command line only")}
    for name, (text, want) in cases.items():
        cfg = tmp_path / f"{name.replace(' ', '_')}.toml"
        cfg.write_text(text)
        res = runner.invoke(app, ["identify", "--config", str(cfg)])
        line = _one_line(res)
        assert res.exit_code == 2 and want in line and "Missing option" not in line, (name, line)


def test_files_only_a_toml_named_are_not_quoted(work, tmp_path):
    """Reproducer: a TOML could name any local file as data (or gains, weights) and the error quoted it."""
    d, _ = work
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'robot = "ur5"\ndata = ["{d / "secret.txt"}"]\nout = "{tmp_path / "o"}"\n')
    res = runner.invoke(app, ["identify", "--config", str(cfg)])
    assert res.exit_code == 2 and SECRET not in res.output and "hunter2" not in res.output
    assert "named by --config" in _one_line(res)
    res = runner.invoke(app, ["identify", "--config", str(cfg), "--data", str(d / "secret.txt")])
    assert res.exit_code == 2 and "hunter2" in res.output  # named on the command line: the details are shown


def test_fifo_and_device_logs_refused_before_opening(work, tmp_path):
    """Reproducers: a FIFO named log.npz/.h5/.parquet blocked `identify` forever (the chunked reader opened
    it); `--data x.npz` pointing at /dev/zero grew to 21 GB."""
    from sensorless.data.chunks import open_chunked

    d, _ = work
    for name in ("log.npz", "log.h5", "log.parquet"):
        os.mkfifo(tmp_path / name)
        with pytest.raises(InputError, match="FIFO"):
            open_chunked(tmp_path / name, load_robot("ur5").joint_names)
        res = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / name), "--out",
                                  str(tmp_path / "o")])
        assert res.exit_code == 2 and "is a FIFO" in _one_line(res)
    (tmp_path / "zero.npz").symlink_to("/dev/zero")
    res = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / "zero.npz"), "--out",
                              str(tmp_path / "o")])
    assert res.exit_code == 2 and "is a device" in _one_line(res)


def _mat73_with_external_names(tmp_path, traj, secret):
    """A v7.3 log whose joint names are a cell array, one item stored externally in ``secret``."""
    path = write_mat73(tmp_path / "ext.mat", {"t": traj.t, "q": traj.q, "v": traj.v, "tau": traj.tau,
                                              "joint_names": CellStr(traj.joint_names)})
    size = os.path.getsize(secret)
    with h5py.File(path, "r+") as f:
        item = f.create_dataset("#refs#/zz", shape=(size // 2, 1), dtype="<u2", external=[(str(secret), 0, size)])
        item.attrs.create("MATLAB_class", np.bytes_("char"))
        cell = f["joint_names"]
        refs = cell[()]
        refs[0, 0] = item.ref
        cell[...] = refs
    return path


def test_mat73_cell_item_with_external_storage_refused(work, tmp_path):
    """Reproducer: a MATLAB v7.3 log whose joint names are a cell array with HDF5 external storage bypassed
    the flag, and `friction` wrote the secret into result.json."""
    d, traj = work
    path = _mat73_with_external_names(tmp_path, traj, d / "secret.txt")
    with pytest.raises(InputError, match="external raw storage"):
        read_trajectory(path)
    res = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(path), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "external raw storage" in _one_line(res) and "hunter2" not in res.output


def test_mat73_item_declaring_huge_text_refused(work, tmp_path):
    """Reproducer: a MATLAB v7.3 item declaring 2·10⁹ characters hung the reader."""
    _, traj = work
    path = write_mat73(tmp_path / "big.mat", {"t": traj.t, "q": traj.q, "v": traj.v, "tau": traj.tau,
                                              "joint_names": CellStr(traj.joint_names)})
    with h5py.File(path, "r+") as f:
        item = f.create_dataset("#refs#/zz", shape=(2_000_000_000, 1), dtype="<u2", chunks=(1 << 16, 1))
        item.attrs.create("MATLAB_class", np.bytes_("char"))
        refs = f["joint_names"][()]
        refs[1, 0] = item.ref
        f["joint_names"][...] = refs
    with pytest.raises(DataError, match=r"declares 2e\+09 characters"):
        read_trajectory(path)


def test_deep_urdf_chain_parser_crash_is_a_typed_error(tmp_path):
    """Reproducer: a URDF with a 5000-link fixed chain (1 MB) segfaulted inside the parser."""
    inertial = '<inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>'
    links = "".join(f'<link name="l{i}">{inertial}</link>' for i in range(5000))
    joints = "".join(f'<joint name="j{i}" type="fixed"><parent link="l{i - 1}"/><child link="l{i}"/>'
                     f'<origin xyz="0 0 0.01"/></joint>' for i in range(1, 5000))
    end = (f'<link name="e">{inertial}</link><joint name="jr" type="revolute"><parent link="l4999"/><child link="e"/>'
           '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>')
    path = tmp_path / "chain.urdf"
    path.write_text(f'<robot name="chain">{links}{end}{joints}</robot>')
    with pytest.raises(RobotModelError, match="parser crashed"):
        load_robot(path)


def test_markup_and_escape_sequences_in_names(tmp_path):
    """Reproducers: a joint named with `[/]` crashed the console tables (rich markup); column names with
    terminal escape sequences reached the terminal."""
    from rich.console import Console

    from sensorless.cli.console import SafeConsole, safe

    out = SafeConsole(file=open(os.devnull, "w"), force_terminal=False)
    out.print("joint a[/]b")  # unparsable markup: plain text, no MarkupError
    buf = SafeConsole(record=True, width=200, file=open(os.devnull, "w"))
    buf.print(f"name {safe('q_[bold]x')} \x1b]0;owned\x07 and \x1b[31mred")
    text = buf.export_text()
    assert "[bold]x" in text and "\x1b" not in text and "\x07" not in text
    assert isinstance(buf, Console)


@pytest.mark.parametrize("name", ["x" * 256, "bad\udcff\udcfe"])
def test_output_names_the_file_system_cannot_hold(work, tmp_path, name):
    """Reproducer: a 256-byte or undecodable --out name was an internal error."""
    d, _ = work
    res = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(d / "good.npz"), "--out",
                              str(tmp_path / name)])
    line = _one_line(res)
    assert res.exit_code == 2 and "internal error" not in line and ("bytes long" in line or "UTF-8" in line)


def test_extreme_resample_is_a_typed_error(work, tmp_path):
    """Reproducer: `--resample 1e12` raised a MemoryError (145 TiB) as an internal error."""
    d, _ = work
    res = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(d / "good.npz"), "--resample", "1e12",
                              "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "more than 100×" in _one_line(res)


def test_chunked_reader_refuses_hdf5_external_storage(work, tmp_path):
    """Reproducer: the chunked reader (logs of 50,000+ samples, or --stream) read HDF5 external storage
    without the flag."""
    from sensorless.data.chunks import open_chunked

    d, traj = work
    raw = tmp_path / "raw.bin"
    raw.write_bytes(np.ascontiguousarray(traj.tau, "<f8").tobytes())
    path = tmp_path / "ext.h5"
    with h5py.File(path, "w") as f:
        f["t"], f["q"], f["v"] = traj.t, traj.q, traj.v
        f.create_dataset("tau", shape=traj.tau.shape, dtype="<f8", external=[(str(raw), 0, raw.stat().st_size)])
    with pytest.raises(InputError, match="external raw storage"):
        open_chunked(path, traj.joint_names)


def test_monitor_out_inside_the_model_folder_refused(work, tmp_path):
    """Reproducer: `monitor --out model/mon` wrote inside the model folder it reads."""
    d, _ = work
    model = tmp_path / "model"
    r = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(d / "good.npz"), "--method", "ols",
                            "--no-plot", "--out", str(model)])
    assert r.exit_code == 0, r.output
    before = sorted(p.name for p in model.iterdir())
    r = runner.invoke(app, ["monitor", "--robot", "ur5", "--model", str(model), "--data", str(d / "good.npz"),
                            "--quiet", "0:2", "--no-plot", "--out", str(model / "mon")])
    assert r.exit_code == 2 and "inside the input folder" in _one_line(r)
    assert sorted(p.name for p in model.iterdir()) == before
