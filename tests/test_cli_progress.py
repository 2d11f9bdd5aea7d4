"""Progress bars (issue 24): drawn on a terminal only, silent under CliRunner, a pipe or
SENSORLESS_PROGRESS=0; the library callbacks behind them count what they say."""

from __future__ import annotations

import io

import numpy as np
import pytest
from rich.console import Console
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.cli import progress as progress_mod
from sensorless.data import write_npz
from sensorless.excitation import design_excitation, random_fourier
from sensorless.excitation.design import PLATEAU_ITERATIONS, PLATEAU_TOL
from sensorless.regressor import ModelStructure
from sensorless.testing import perturbed_truth, synthetic_trajectory


@pytest.fixture(scope="module")
def ur5_logs(tmp_path_factory, ur5):
    d = tmp_path_factory.mktemp("ur5_logs")
    truth = perturbed_truth(ur5, rng=0)
    paths = []
    for k in range(3):
        tr = synthetic_trajectory(truth, random_fourier(ur5, rng=10 + k).sample(50, 6.0), noise_std=0.05, rng=k)
        paths.append(str(write_npz(tr, d / f"log{k}.npz")))
    return paths


def _identify(paths, out):
    return CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", *paths[:2], "--validate", paths[2],
                                    "--method", "ols", "--joint-terms", "fv,fc,offset", "--coulomb-smoothing", "0.02",
                                    "--no-plot", "--out", str(out)])


def _terminal(monkeypatch) -> io.StringIO:
    buf = io.StringIO()
    monkeypatch.setattr(progress_mod, "console", Console(file=buf, force_terminal=True, width=120))
    return buf


def test_cli_runner_output_has_no_progress_bar(ur5_logs, tmp_path):
    res = _identify(ur5_logs, tmp_path / "id")
    assert res.exit_code == 0, res.output
    text = res.output + (res.stderr if res.stderr_bytes is not None else "")
    assert "reading logs" not in text and "regressor (samples)" not in text


def test_a_terminal_shows_the_bars_of_an_identify_over_several_logs(ur5_logs, tmp_path, monkeypatch):
    monkeypatch.delenv(progress_mod.PROGRESS_ENV, raising=False)
    buf = _terminal(monkeypatch)
    res = _identify(ur5_logs, tmp_path / "id")
    assert res.exit_code == 0, res.output
    shown = buf.getvalue()
    assert "reading logs" in shown and "3/3" in shown  # two training logs and the held-out one
    n = 2 * 300  # samples of the two training logs
    assert "regressor (samples)" in shown and f"{n}/{n}" in shown
    assert "OLS baseline" not in shown  # --method ols is its own baseline


def test_sensorless_progress_0_silences_a_terminal(ur5_logs, tmp_path, monkeypatch):
    buf = _terminal(monkeypatch)
    monkeypatch.setenv(progress_mod.PROGRESS_ENV, "0")
    res = _identify(ur5_logs, tmp_path / "id")
    assert res.exit_code == 0, res.output
    assert buf.getvalue() == ""
    assert not progress_mod.progress_enabled(progress_mod.console)


def test_steps_are_no_ops_when_off():
    with progress_mod.progress_bars(enabled=False) as bars:
        bars.step("x", total=3).advance(2)
        assert bars.callback("y") is None
        bars.close()


def test_excitation_progress_counts_iterations_and_stops_on_a_plateau(ur5):
    s = ModelStructure(ur5, joint_terms=("fv", "fc", "offset"))
    calls = []
    d = design_excitation(s, harmonics=2, base_freq=0.2, n_samples=40, maxiter=300, n_random=1, seed=0,
                          progress=lambda i, f: calls.append((i, f)))
    n = d.settings["iterations"]
    assert [i for i, _ in calls] == list(range(1, n + 1))
    assert all(np.isfinite(f) for _, f in calls)
    # the criterion reported is that of each iterate brought inside the limits; the best is returned
    assert np.exp(min(f for _, f in calls)) == pytest.approx(d.metrics["cond"], rel=1e-6)
    if d.settings["stopped_by"] == "plateau":
        last = [f for _, f in calls[-PLATEAU_ITERATIONS:]]
        assert n < 300 and max(last) - min(last) < PLATEAU_TOL
    else:  # SLSQP's own test or the iteration cap: then no earlier window was flat
        flat = [max(w) - min(w) < PLATEAU_TOL for w in (
            [f for _, f in calls[k - PLATEAU_ITERATIONS:k]] for k in range(PLATEAU_ITERATIONS, n + 1))]
        assert not any(flat)
    assert max(d.limit_violation.values()) <= 0


def test_cli_excite_in_a_terminal_shows_the_iteration_bar(tmp_path, monkeypatch):
    monkeypatch.delenv(progress_mod.PROGRESS_ENV, raising=False)
    buf = _terminal(monkeypatch)
    res = CliRunner().invoke(app, ["excite", "--robot", "ur5", "--harmonics", "2", "--base-freq", "0.2",
                                   "--n-samples", "40", "--maxiter", "5", "--rate", "20", "--out", str(tmp_path / "ex")])
    assert res.exit_code == 0, res.output
    assert "optimising excitation" in buf.getvalue() and "/5" in buf.getvalue() and "cond" in buf.getvalue()
    assert "optimising excitation" not in res.output
