"""Drives as they are (issue #44): a bench logging the motor current and the output torque, the gain
estimated with the friction, load-dependent Coulomb friction, directional efficiency, held-out choice.

The simulated bench (:mod:`sensorless_studies.simulation.drive_bench`) carries the effects with a
quantized encoder and noisy current and output torque; v and v̇ come from q as a lab's log would give
them. Acceptance: every parameter inside its 95 % interval (the 20-seed rate is the slow test), and the
held-out output-torque error of the model the held-out choice keeps within 1.1× the noise floor.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data.bench_log import read_bench_log
from sensorless.errors import DataError
from sensorless.identification.friction_fit import JointSeries, fit_joint_friction
from sensorless.identification.friction_model import FrictionModel, measured_torque
from sensorless.regressor.friction_state import FrictionLaw
from sensorless_studies.simulation.drive_bench import DriveBench, drive_noise, simulate_drive_bench, write_drive_csv

runner = CliRunner(env={"COLUMNS": "200"})  # tables unwrapped, as in a wide terminal
LOAD = DriveBench(load=0.15)  # Coulomb growing with the transmitted torque (a strain-wave gear)
BACK = DriveBench(gain_back=-0.1)  # 20 % less torque per ampere when back-driven
FIXED = {"load": ("fc", "fv", "offset", "load"), "back": ("fc", "fv", "offset", "gain_back")}


def _logs(bench, tmp_path, seed: int, n: int = 3, duration: float = 30.0) -> list:
    return [read_bench_log(write_drive_csv(simulate_drive_bench(bench, seed=10 * seed + i, duration=duration),
                                           tmp_path / f"s{seed}_{i}.csv"))
            for i in range(n)]


def _covered(bench, terms, logs) -> dict:
    """{term: truth inside the 95 % interval} of the fit with the bench's own terms."""
    fit = FrictionModel(terms, "off", bench.eps).fit(logs).fits_["joint"]
    return {t: fit.intervals[t] is not None and fit.intervals[t][0] <= v <= fit.intervals[t][1]
            for t, v in bench.truth().items()}


@pytest.mark.parametrize("name,bench", [("load", LOAD), ("back", BACK)])
def test_drive_bench_parameters_inside_their_intervals(name, bench, tmp_path):
    for seed in (0, 1):
        cov = _covered(bench, FIXED[name], _logs(bench, tmp_path, seed))
        assert all(cov.values()), (seed, cov)


def test_held_out_choice_keeps_a_model_within_the_noise_and_the_plain_one_is_worse(tmp_path):
    logs = _logs(LOAD, tmp_path, 3, n=3, duration=20.0)
    test = logs.pop()
    model = FrictionModel(state="off").fit(logs)
    law = model.laws_["joint"]
    assert law.is_drive and "load" in law.coef
    rms = lambda m: float(np.sqrt(np.mean((m.predict(test)[:, 0] - measured_torque(test, "joint")) ** 2)))  # noqa: E731
    assert rms(model) <= 1.1 * drive_noise(LOAD)
    plain = FrictionModel(("fc", "fv", "offset"), "off").fit(logs)
    assert rms(plain) > 1.5 * drive_noise(LOAD)
    held = model.fits_["joint"].held_out
    assert held["by"] == "log" and held["folds"] == 2


def test_output_torque_inverts_the_load_term_exactly():
    rng = np.random.default_rng(0)
    v, tau_out = rng.normal(0, 0.3, 400), rng.normal(0.2, 0.5, 400)
    law = FrictionLaw("static", {"fc": 0.04, "fv": 0.02, "offset": 0.01, "gain": 0.5, "gain_back": -0.1,
                                 "load": 0.15}, eps=0.02)
    s = np.tanh(v / 0.02)
    m = tau_out + (0.04 + 0.15 * np.abs(tau_out)) * s + 0.02 * v + 0.01
    u = m / (0.5 - 0.1 * np.maximum(0.0, -np.sign(m) * s))
    np.testing.assert_allclose(law.output_torque(np.zeros_like(v), v, drive=u), tau_out, atol=1e-9)
    np.testing.assert_allclose(law.torque(np.zeros_like(v), v, drive=u, load=tau_out), -tau_out, atol=1e-9)


def _series(bench, seed=0, flip=()):
    tr = simulate_drive_bench(bench, seed=seed, duration=10.0)
    q = tr.q[:, 0]
    u, out = (np.asarray(tr.extras["current"])[:, 0], np.asarray(tr.extras["tau_out"])[:, 0])
    v = np.gradient(q, tr.t)
    sign = {k: (-1.0 if k in flip else 1.0) for k in ("current", "tau_out", "q")}
    return JointSeries(tr.t, sign["q"] * q, sign["q"] * v, sign["tau_out"] * out, drive=sign["current"] * u)


@pytest.mark.parametrize("flip,cause", [(("tau_out",), "output torque's sign is reversed"),
                                        (("current",), "drive input's sign"), (("q",), "position and velocity")])
def test_a_reversed_sign_is_refused_with_its_cause_and_flag(flip, cause):
    assert fit_joint_friction([_series(LOAD)], terms=("fc", "fv", "offset"), state="off").law.coef["gain"] > 0
    with pytest.raises(DataError, match=cause) as err:
        fit_joint_friction([_series(LOAD, flip=flip)], terms=("fc", "fv", "offset"), state="off")
    assert f"`flip={flip[0]!r}`" in str(err.value)


def test_cli_takes_current_and_output_torque_and_pools_test_groups(tmp_path):
    paths = [write_drive_csv(simulate_drive_bench(LOAD, seed=s, duration=10.0), tmp_path / f"b{s}.csv")
             for s in range(4)]
    flipped = [tmp_path / f"flipped{i}.csv" for i in (0, 1)]
    for p, f in zip(paths, flipped):
        pd.read_csv(p).assign(tau_out=lambda d: -d.tau_out).to_csv(f, index=False)
    args = ["friction", "--terms", "fc,fv,offset,load", "--state", "off", "--no-plot"]
    r = runner.invoke(app, [*args, "--data", str(flipped[0]), "--data", str(flipped[1]), "--out", str(tmp_path / "x")])
    assert r.exit_code != 0 and "--flip tau_out" in r.output, r.output
    # one log of two counting the other way: refused, naming it
    r = runner.invoke(app, [*args, "--data", str(flipped[0]), "--data", str(paths[1]), "--data", str(paths[2]),
                            "--out", str(tmp_path / "x")])
    assert r.exit_code != 0 and "opposite signs" in r.output and "flipped0.csv" in r.output, r.output
    assert not (tmp_path / "x").exists()
    r = runner.invoke(app, [*args, "--data", str(paths[0]), "--data", str(paths[1]), "--test", f"A={paths[2]}",
                            "--test", f"A={paths[3]}", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    flat = " ".join(r.output.split())  # a narrow terminal wraps the titles
    assert "pooled per group" in flat and "linear K·u +" in flat
    doc = json.loads((tmp_path / "m" / "result.json").read_text())
    pooled = doc["validation_groups"]["A"]["joint"]
    assert pooled["logs"] == 2 and pooled["model"] <= 1.1 * drive_noise(LOAD)
    assert pooled["linear K·u + o"] > pooled["linear + Coulomb/viscous"] > pooled["model"]
    assert doc["laws"]["joint"]["coef"]["gain"] == pytest.approx(LOAD.gain, rel=0.01)
    from sensorless.data.gains import load_gains  # the fitted gain, as a file --gains reads

    gains = load_gains(tmp_path / "m" / "gains.json")
    lo, hi = json.loads((tmp_path / "m" / "gains.json").read_text())["intervals"]["joint"]
    assert gains["joint"] == pytest.approx(LOAD.gain, rel=0.01) and lo < gains["joint"] < hi  # coverage: slow test
    r = runner.invoke(app, ["predict", "--model", str(tmp_path / "m"), "--data", str(paths[3]),
                            "--out", str(tmp_path / "p.npz")])
    assert r.exit_code == 0, r.output
    z = np.load(tmp_path / "p.npz")
    assert float(np.sqrt(np.mean((z["tau_pred"] - z["tau_measured"]) ** 2))) <= 1.1 * drive_noise(LOAD)
    r = runner.invoke(app, ["monitor", "--model", str(tmp_path / "m"), "--data", str(paths[3]), "--quiet", "0:3",
                            "--out", str(tmp_path / "mon")])
    assert r.exit_code != 0 and "observer does not take" in r.output, r.output


def test_commented_header_of_a_lab_logger_is_read(tmp_path):
    p = tmp_path / "RUN.TXT"
    p.write_text("%bench v1\n%Time [s], Jaw [counts], Current [A]\n0.000,1,0.5\n0.001,2,0.25\n0.002,3,0.1\n")
    from sensorless.data.tabular import read_text_table

    df, header = read_text_table(p)
    assert header and list(df.columns) == ["Time [s]", "Jaw [counts]", "Current [A]"] and len(df) == 3


@pytest.mark.slow
@pytest.mark.parametrize("name,bench", [("load", LOAD), ("back", BACK)])
def test_drive_bench_coverage_over_20_seeds(name, bench, tmp_path):
    hits = {t: 0 for t in bench.truth()}
    ratios = []
    for seed in range(20):
        logs = _logs(bench, tmp_path, 100 + seed, n=4)
        test = logs.pop()
        for t, ok in _covered(bench, FIXED[name], logs).items():
            hits[t] += ok
        model = FrictionModel(state="off").fit(logs)
        e = model.predict(test)[:, 0] - measured_torque(test, "joint")
        ratios.append(float(np.sqrt(np.mean(e**2))) / drive_noise(bench))
    print(f"{name}: inside the 95 % interval in {hits} of 20 seeds; held-out RMSE / noise max {max(ratios):.3f}, "
          f"median {np.median(ratios):.3f}")
    assert all(h >= 18 for h in hits.values()), hits
    assert max(ratios) <= 1.1, ratios


def test_an_output_torque_without_a_drive_input_is_refused(tmp_path):
    p = write_drive_csv(simulate_drive_bench(LOAD, seed=0, duration=2.0), tmp_path / "b.csv")
    pd.read_csv(p)[["t", "q", "tau_out"]].to_csv(tmp_path / "out_only.csv", index=False)
    with pytest.raises(DataError, match="output torque 'tau_out' with the current"):
        read_bench_log(tmp_path / "out_only.csv")
