"""Untrusted robot descriptions (issue 26 item 2): xacro runs nothing without consent, trusted
expansion is bounded in time and memory. File references: tests/test_robot_paths.py."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.errors import RobotModelError, UntrustedModelError
from sensorless.robot import load_robot

runner = CliRunner()
HEAD = '<?xml version="1.0"?>\n<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="{name}">\n'
ARM = """  <link name="base"/>
  <link name="l1"><inertial><mass value="2.0"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.005"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="50" velocity="3"/></joint>
</robot>
"""
RP = "${'\\x29'}"  # a ')' that xacro's $( ) lexer does not see


def _proofs(folder: Path, marker: Path) -> dict[str, Path]:
    """Three xacro files that run code (xacro 2.1.1): each writes ``marker`` (``id`` output or
    a copy of /etc/passwd) when expanded."""
    p1 = folder / "escape.urdf.xacro"  # ${} sandbox escape through type.__subclasses__
    p1.write_text(HEAD.format(name="escape") + f"""
  <xacro:property name="o" value="${{python.int.mro()[-1]}}"/>
  <xacro:property name="w" value="${{[c for c in python.vars(python.type)['__subclasses__'](o)
      if '_wrap_close' in python.str(c)][0]}}"/>
  <xacro:property name="g" value="${{python.vars(o)['__getattribute__'](python.vars(w)['__init__'], '__globals__')}}"/>
  <material name="x${{g['system']('id > {marker}')}}"/>
""" + ARM)
    p2 = folder / "evalexec.urdf.xacro"  # $(eval ...) runs with the real builtins
    p2.write_text(HEAD.format(name="evalexec") + f"""
  <material name="x$(eval exec(&quot;import os;os.system('id > {marker}'{RP}&quot;,{{}}{RP} or '')"/>
""" + ARM)
    (folder / "parts.xacro").write_text(HEAD.format(name="parts") + f"""
  <material name="leak_$(eval str(open('{marker}','w'{RP}.write(open('/etc/passwd'{RP}.read({RP}{RP}{RP})"/>
</robot>
""")
    p3 = folder / "innocent.urdf.xacro"  # an innocent-looking file whose include copies /etc/passwd
    p3.write_text(HEAD.format(name="innocent") + '  <xacro:include filename="parts.xacro"/>\n' + ARM)
    return {"escape": p1, "evalexec": p2, "include": p3}


def _cli(command: str, robot: Path, tmp: Path, *extra: str):
    args = {"identify": ["--data", str(tmp / "log.csv"), "--out", str(tmp / "out_id")],
            "excite": ["--out", str(tmp / "out_ex")],
            "predict": ["--model", str(tmp / "model"), "--data", str(tmp / "log.csv"), "--out", str(tmp / "p.npz")]}
    return runner.invoke(app, [command, "--robot", str(robot), *args[command], *extra])


@pytest.fixture
def proofs(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    marker = tmp_path / "PWNED"
    return _proofs(tmp_path, marker), marker


@pytest.mark.parametrize("command", ["identify", "excite", "predict"])
def test_no_xacro_proof_runs_without_trust_xacro(proofs, tmp_path, command):
    files, marker = proofs
    for name, path in files.items():
        res = _cli(command, path, tmp_path)
        assert res.exit_code == 2, (name, res.output)
        assert not marker.exists(), f"{name}: code ran in {command}"
        line = " ".join(res.output.split())
        assert "can run code" in line and "--trust-xacro" in line and f"xacro {path} > robot.urdf" in line, line
        assert "trust_xacro=" not in line
    assert not (tmp_path / "cache").exists()  # nothing expanded, nothing cached


def test_library_refuses_xacro_by_default_and_names_the_keyword(proofs):
    files, marker = proofs
    for path in files.values():
        with pytest.raises(UntrustedModelError, match=r"can run code.*trust_xacro=True"):
            load_robot(path)
    assert not marker.exists()


def test_the_proofs_are_real_with_trust_xacro(proofs):
    """The same files do run code once trusted (so the refusal above is what stops them)."""
    pytest.importorskip("xacro")
    files, marker = proofs
    for name, path in files.items():
        marker.unlink(missing_ok=True)
        r = load_robot(path, trust_xacro=True)
        assert r.joint_names == ("j1",) and marker.exists(), name
    assert "root:" in marker.read_text()  # the include proof copied /etc/passwd


def test_benign_xacro_loads_with_trust_xacro(tmp_path, monkeypatch):
    pytest.importorskip("xacro")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    path = tmp_path / "arm.urdf.xacro"
    path.write_text(HEAD.format(name="arm") + '  <xacro:property name="m" value="2.0"/>\n'
                    + ARM.replace('"2.0"', '"${m * 1.5}"'))
    res = _cli("excite", path, tmp_path, "--trust-xacro", "--maxiter", "2", "--n-samples", "100")
    assert res.exit_code == 0, res.output
    assert load_robot(path, trust_xacro=True).model.inertias[1].mass == 3.0


@pytest.mark.parametrize("body", [
    '  <link name="x${9**9**9}"/>\n',
    '  <xacro:macro name="m0"><link name="x"/></xacro:macro>\n'
    + "".join(f'  <xacro:macro name="m{i}"><xacro:m{i - 1}/><xacro:m{i - 1}/></xacro:macro>\n' for i in range(1, 40))
    + "  <xacro:m39/>\n",
], ids=["power-tower", "exponential-macro"])
def test_trusted_expansion_is_stopped_at_its_time_limit(tmp_path, monkeypatch, body):
    pytest.importorskip("xacro")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("SENSORLESS_XACRO_TIMEOUT", "3")
    path = tmp_path / "hang.urdf.xacro"
    path.write_text(HEAD.format(name="hang") + body + ARM)
    t0 = time.monotonic()
    res = _cli("excite", path, tmp_path, "--trust-xacro")
    elapsed = time.monotonic() - t0
    assert res.exit_code == 2 and elapsed < 3 + 3, (elapsed, res.output)
    line = " ".join(res.output.split())
    assert f"{path}: xacro expansion stopped" in line and "3 s" in line and "SENSORLESS_XACRO_TIMEOUT" in line


def test_trusted_expansion_is_stopped_at_its_memory_limit(tmp_path, monkeypatch):
    pytest.importorskip("xacro")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("SENSORLESS_XACRO_MEMORY_MB", "300")
    path = tmp_path / "mem.urdf.xacro"
    path.write_text(HEAD.format(name="mem") + "  <link name=\"x${python.len('x' * 2**30)}\"/>\n" + ARM)
    with pytest.raises(RobotModelError, match=r"mem.urdf.xacro: xacro expansion ran out of its 300 MiB memory limit"):
        load_robot(path, trust_xacro=True)


def test_trust_xacro_is_not_taken_from_a_config_file(proofs, tmp_path):
    files, marker = proofs
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'trust_xacro = true\nrobot = "{files["escape"]}"\n')
    res = runner.invoke(app, ["identify", "--config", str(cfg), "--data", str(tmp_path / "x.csv"),
                              "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "command line only" in res.output and not marker.exists()


def _alive_with(arg: str) -> list[int]:
    import os

    out = []
    for e in os.listdir("/proc"):
        if e.isdigit():
            try:
                with open(f"/proc/{e}/cmdline", "rb") as fh:
                    if arg.encode() in fh.read():
                        out.append(int(e))
            except OSError:
                pass
    return out


@pytest.mark.parametrize("block", [False, True])
def test_trusted_xacro_children_that_setsid_are_killed(tmp_path, monkeypatch, block):
    """Issue #41 reproducer: a process a trusted xacro file started with `setsid` (its own session and
    process group) outlived the expansion's limits. The worker is a subreaper that kills every descendant,
    when the expansion ends and when the time limit stops it."""
    pytest.importorskip("xacro")
    import sys

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("SENSORLESS_XACRO_TIMEOUT", "3")
    tag = f"{371 + int(block)}.{time.time_ns() % 10**6}"
    code = (f"import subprocess;subprocess.Popen(['setsid','{sys.executable}','-c','import time;time.sleep({tag})'])"
            + (";import time;time.sleep(60)" if block else "")).replace(")", RP)
    path = tmp_path / "spawn.urdf.xacro"
    path.write_text(HEAD.format(name="spawn") + f"""
  <material name="x$(eval exec(&quot;{code}&quot;,{{}}{RP} or '')"/>
""" + ARM)
    if block:
        with pytest.raises(RobotModelError, match="time limit"):
            load_robot(path, trust_xacro=True)
    else:
        load_robot(path, trust_xacro=True)
    deadline = time.time() + 5
    while _alive_with(f"time.sleep({tag})") and time.time() < deadline:
        time.sleep(0.05)
    assert not _alive_with(f"time.sleep({tag})")
