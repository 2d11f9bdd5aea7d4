"""`sensorless identify`'s fixed costs removed without changing its output (issue 28, deliverable 1).
No timing assertions: the times are in ``sensorless benchmark identify-e2e``.

* friction.png evaluates only the samples it draws: the same dots as evaluating every sample;
* the figure process draws the same PNG bytes as the command's own process (also the half of its
  jobs drawn by its forked copy), and when it fails
  (or no core is idle for it) the command draws them itself (exit 0, every figure written);
* the OLS baseline solved on the fit's compressed equations (Stribeck candidates selected) equals
  a second pass over the logs;
* ``identify(validated=True)`` (the CLI's logs, checked once by the reader) gives the same result;
* the benchmark runs fresh processes and records both times.
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.excitation import random_fourier
from sensorless.identification import identify
from sensorless.identification.friction import friction_residual
from sensorless.identification.friction_search import identify_friction
from sensorless.regressor import ModelStructure
from sensorless.testing import perturbed_truth, synthetic_trajectory


def _log(robot, seconds: float, rate: float = 200.0, rng: int = 1):
    truth = perturbed_truth(robot, rng=0)
    return synthetic_trajectory(truth, random_fourier(robot, rng=rng).sample(rate, seconds), noise_std=0.1, rng=rng + 1)


def test_friction_dots_from_the_drawn_samples_equal_those_of_every_sample(ur5):
    from sensorless.report.friction_plot import friction_panels

    s = ModelStructure(ur5, joint_terms=("fv", "fc", "offset", "armature"))
    logs = [_log(ur5, 12.0, rng=1), _log(ur5, 15.0, rng=3)]  # 2400 + 3000 samples > 4000 drawn
    params = s.prior() + np.random.default_rng(0).normal(scale=0.05, size=s.n_params)
    pairs = [friction_residual(s, params, t) for t in logs]
    V, R = np.concatenate([v for v, _ in pairs]), np.concatenate([r for _, r in pairs])
    idx = np.random.default_rng(0).choice(len(V), 4000, replace=False)
    panels = friction_panels(s, params, logs, max_points=4000)
    np.testing.assert_allclose(panels["V"], V[idx], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(panels["R"], R[idx], rtol=1e-12, atol=1e-9)
    assert [lab[0].split(":")[0] for lab in panels["labels"]] == list(ur5.term_joints)


def test_figure_process_writes_the_png_the_command_would(tmp_path):
    from sensorless.cli.figure_process import FigureProcess
    from sensorless.report.plot_process import draw_job

    t = np.linspace(0.0, 2.0, 300)
    meas = np.stack([np.sin(t), np.cos(t)], axis=1)
    job = dict(t=t, measured=meas, predictions={"LMI": 0.9 * meas, "CAD": 1.1 * meas}, rows=["a", "b"],
               units=["N·m", "N"], title="test")
    with FigureProcess() as fp:
        assert fp.submit([("torques", job, tmp_path / "child.png")])
        assert fp.wait()
    draw_job("torques", job, tmp_path / "here.png")
    assert (tmp_path / "child.png").read_bytes() == (tmp_path / "here.png").read_bytes()


def test_submitting_jobs_larger_than_the_pipe_does_not_wait_for_the_child(tmp_path, monkeypatch):
    """The jobs outgrow a pipe's buffer and the child reads them only once warmed up: ``submit`` returns
    at once (a thread writes), and ``close`` ends a child that never reads without a deadlock."""
    import threading

    from sensorless.cli.figure_process import FigureProcess

    never_reads = tmp_path / "python"
    never_reads.write_text("#!/bin/sh\nexec sleep 60\n")
    never_reads.chmod(0o755)
    monkeypatch.setattr(sys, "executable", str(never_reads))
    big = np.random.default_rng(0).normal(size=(200_000, 2))  # 3.2 MB pickled, beyond any pipe buffer
    done = {}

    def run():
        fp = FigureProcess()
        done["submitted"] = fp.submit([("torques", dict(t=big[:, 0], measured=big), tmp_path / "x.png")])
        fp.close()
        done["closed"] = True

    th = threading.Thread(target=run, daemon=True)
    th.start()
    th.join(30.0)
    assert done == {"submitted": True, "closed": True}
    assert not (tmp_path / "x.png").exists()


def test_forked_drawing_writes_the_same_pngs_and_surfaces_a_failed_job(tmp_path):
    """The figure process draws half its jobs in a forked copy: the same bytes as drawing them in
    order here; a job the copy cannot draw is drawn again here, so its error is raised, not lost."""
    from sensorless.report.plot_process import draw_jobs

    t = np.linspace(0.0, 2.0, 300)
    meas = np.stack([np.sin(t), np.cos(t)], axis=1)
    jobs = [("torques", dict(t=t, measured=meas * k, predictions={"LMI": 0.9 * meas}, rows=["a", "b"],
                             units=["N·m", "N"], title=f"job {k}"), tmp_path / f"{name}{k}.png")
            for k in (1, 2, 3) for name in ("forked",)]
    draw_jobs(jobs, fork=True)
    draw_jobs([(kind, kw, tmp_path / path.name.replace("forked", "serial")) for kind, kw, path in jobs], fork=False)
    for k in (1, 2, 3):
        assert (tmp_path / f"forked{k}.png").read_bytes() == (tmp_path / f"serial{k}.png").read_bytes()
    bad = [jobs[0], ("no-such-figure", {}, tmp_path / "bad.png")]  # the second job goes to the copy
    with pytest.raises(ValueError, match="no-such-figure"):
        draw_jobs(bad, fork=True)
    assert not (tmp_path / "bad.png").exists()


def test_figures_built_before_their_data_give_the_same_pngs(ur5, tmp_path):
    """The layouts a run announces before its fit are those of the jobs it sends after; a figure the
    child built empty and drew once, then filled with the job, is the PNG drawn afresh, and a job
    whose layout differs from the prepared one is drawn afresh."""
    from sensorless.report.plot_process import draw_job, job_layout, prepare_layouts
    from sensorless.run import RunConfig, identify_run

    log = _log(ur5, 10.0)  # a plain t, q, dq, tau file: read chunk by chunk when long, so read only in the fit
    np.savez(tmp_path / "log.npz", t=log.t, q=log.q, dq=log.v, tau=log.tau)
    f = tmp_path / "log.npz"
    seen: dict = {}
    identify_run(RunConfig.from_options(robot="ur5", data=[str(f)], method="ols", out=str(tmp_path / "m")),
                 figures=lambda jobs: seen.setdefault("jobs", jobs),
                 figure_layouts=lambda layouts: seen.setdefault("layouts", layouts))
    jobs = seen["jobs"]
    assert sorted(k for k, _, _ in jobs) == ["friction", "torques"]
    assert [(k, tuple(lay), str(p)) for k, lay, p in seen["layouts"]] == \
        [(k, job_layout(k, kw), str(p)) for k, kw, p in jobs]
    for kind, kw, path in jobs:
        prepared = prepare_layouts([(kind, job_layout(kind, kw), tmp_path / f"ready_{kind}.png")])
        draw_job(kind, kw, tmp_path / f"ready_{kind}.png", prepared=prepared)
        draw_job(kind, kw, tmp_path / f"fresh_{kind}.png")
        assert (tmp_path / f"ready_{kind}.png").read_bytes() == (tmp_path / f"fresh_{kind}.png").read_bytes(), kind
    kind, kw, _ = next(j for j in jobs if j[0] == "torques")
    n, titled = job_layout(kind, kw)
    other = prepare_layouts([(kind, (n - 1, titled), tmp_path / "other.png")])
    draw_job(kind, kw, tmp_path / "other.png", prepared=other)
    assert (tmp_path / "other.png").read_bytes() == (tmp_path / "fresh_torques.png").read_bytes()


def test_identify_draws_its_figures_itself_when_the_figure_process_fails(ur5, tmp_path, monkeypatch):
    f = write_npz(_log(ur5, 10.0), tmp_path / "log.npz")
    monkeypatch.setattr("sensorless.cli.figure_process.idle_core", lambda: True)  # whatever the load
    monkeypatch.setattr(sys, "executable", "/bin/false")  # the child exits at once, without drawing
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(f), "--method", "ols",
                                 "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    for name in ("torques.png", "friction.png", "result.json", "report.html"):
        assert (tmp_path / "m" / name).stat().st_size > 1000, name
    assert "data:image/png;base64" in (tmp_path / "m" / "report.html").read_text()


def test_ols_baseline_on_the_compressed_equations_equals_a_second_pass(ur5):
    train = _log(ur5, 20.0)
    s = ModelStructure(ur5, joint_terms=("fv", "fc", "stribeck", "offset", "armature"))
    result, fit = identify_friction(s, [train], identify_kwargs=dict(method="wls"))
    assert fit.stribeck_grid  # the equations are the selected candidates' ones
    from_equations = identify(result.structure, result.equations, method="ols")
    second_pass = identify(result.structure, [train], method="ols")
    scale = np.abs(second_pass.parameters).max()
    assert np.abs(from_equations.parameters - second_pass.parameters).max() < 1e-9 * scale
    w1, w2 = from_equations.diagnostics["row_weights"], second_pass.diagnostics["row_weights"]
    assert w1.keys() == w2.keys() and all(abs(w1[j] - w2[j]) < 1e-9 * w2[j] for j in w2)


def test_identify_on_logs_validated_by_the_reader_is_unchanged(ur5, tmp_path):
    from sensorless.data import read_trajectory

    f = write_npz(_log(ur5, 6.0), tmp_path / "log.npz")
    traj = read_trajectory(f, robot=ur5)
    a = identify(ur5, [traj], method="ols", outliers="keep")
    b = identify(ur5, [traj], method="ols", outliers="keep", validated=True)
    assert np.array_equal(a.parameters, b.parameters)
    assert a.diagnostics["joint_position_range"] == b.diagnostics["joint_position_range"]


@pytest.mark.slow  # ~30 s: fifteen identify processes and the breakdown; the figures themselves come from the benchmark run
def test_benchmark_identify_e2e_records_both_times_per_case(tmp_path):
    out = tmp_path / "e2e.json"
    r = CliRunner().invoke(app, ["benchmark", "identify-e2e", "--repeats", "1", "--long-samples", "3000",
                                 "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    for case in ("hard", "hard_ols", "long"):
        s = doc["seconds"][case]
        assert 0 < s["result_json"]["best"] <= s["exit"]["best"] and s["cpu"]["best"] > 0
    assert doc["seconds"]["python"]["exit"]["best"] < doc["seconds"]["hard"]["exit"]["best"]
    assert doc["long_samples"] == 3000
    imports = doc["breakdown"]["imports"]  # where the wait goes: steps that add up, in the command's order
    assert sum(v["step"] for v in imports.values()) == pytest.approx(list(imports.values())[-1]["cumulative"])
    lmi, ols = doc["breakdown"]["compute"]["hard"], doc["breakdown"]["compute"]["hard_ols"]
    for run in (lmi, ols):
        assert 0 < sum(run["steps"].values()) <= run["total"]
    assert "gamma_cv" in lmi["steps"] and "gamma_cv" not in ols["steps"]
    assert "ols" in ols["steps"] and "final_lmi" in lmi["steps"]


def test_a_task_runnable_for_an_instant_does_not_take_the_figure_process_away(monkeypatch):
    """idle_core reads the runnable count a few times: one busy read (a poller, a shell) among idle
    ones leaves the figures to the child; a machine busy at every read does not."""
    import io

    from sensorless.cli import figure_process

    cores = len(os.sched_getaffinity(0))
    if cores < 2 or not os.path.exists("/proc/loadavg"):
        pytest.skip("needs two cores and /proc/loadavg")
    reads = []

    def fake_open(counts):
        def opener(path, *a, **k):
            n = counts[min(len(reads), len(counts) - 1)]
            reads.append(n)
            return io.StringIO(f"0.5 0.5 0.5 {n}/80 1234\n")
        return opener

    monkeypatch.setattr(figure_process, "open", fake_open([cores, 1]), raising=False)
    assert figure_process.idle_core(spacing=0.0) and reads == [cores, 1]
    reads.clear()
    monkeypatch.setattr(figure_process, "open", fake_open([cores + 1]), raising=False)
    assert not figure_process.idle_core(spacing=0.0) and len(reads) == 5


def test_figures_built_before_the_jobs_in_the_figure_process_are_the_pngs_drawn_here(tmp_path):
    """Layouts first (as identify sends them): the figure process builds the empty figures; the jobs
    then give the PNGs drawing them here gives. A job the forked copy fails is drawn again by the
    child, whose failure the command sees (wait() is False: it draws them itself)."""
    from sensorless.cli.figure_process import FigureProcess
    from sensorless.report.plot_process import draw_job, job_layout

    t = np.linspace(0.0, 2.0, 300)
    meas = np.stack([np.sin(t), np.cos(t), t], axis=1)
    jobs = [("torques", dict(t=t, measured=meas[:, :n] * k, predictions={"LMI": 0.9 * meas[:, :n]},
                             rows=list("abc")[:n], units=["N·m"] * n, title=f"job {k}"), tmp_path / f"child{k}.png")
            for k, n in ((1, 2), (2, 3))]
    layouts = [(kind, job_layout(kind, kw), path) for kind, kw, path in jobs]
    with FigureProcess() as fp:
        fp.prepare(layouts)
        assert fp.submit(jobs) and fp.wait()
    for kind, kw, path in jobs:
        draw_job(kind, kw, tmp_path / path.name.replace("child", "here"))
        assert path.read_bytes() == (tmp_path / path.name.replace("child", "here")).read_bytes()
    bad = [jobs[0][:2] + (tmp_path / "good.png",), ("no-such-figure", {}, tmp_path / "bad.png")]
    with FigureProcess() as fp:
        fp.prepare([layouts[0][:2] + (tmp_path / "good.png",), ("torques", (3, True), tmp_path / "bad.png")])
        assert fp.submit(bad) and not fp.wait()
    assert not (tmp_path / "bad.png").exists()
