"""sensorless.run.checks: values no run can use are refused before any work, with an OptionError naming
the configuration field; the command names its flag for the same mistake."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.errors import OptionError
from sensorless.run import RunConfig
from sensorless.run.checks import auto_or_number, check_run_config

BAD = [  # (options, the field the message names, its flag, what the message says)
    (dict(workers=2), "execution.workers", "--workers", "needs"),
    (dict(scheduler="local", joint_terms="fv,presliding"), "model.joint_terms", "--joint-terms", "presliding"),
    (dict(gamma="lots"), "solver.gamma", "--gamma", "must be a number or 'auto'"),
    (dict(gamma="-1"), "solver.gamma", "--gamma", ">= 0"),
    (dict(coulomb_smoothing="nan"), "model.coulomb_smoothing", "--coulomb-smoothing", "finite"),
    (dict(stribeck_velocity="0"), "model.stribeck_velocity", "--stribeck-velocity", "> 0"),
    (dict(wrench_frame=("lf:foot",)), "logs.wrench_frame", "--wrench-frame", "wrench"),
    (dict(method="newton"), "solver.method", None, "must be one of ols, wls, svd, lmi"),
    (dict(urdf_values="cad"), "solver.urdf_values", None, "must be one of prior, regularised"),
    (dict(outliers="ignore"), "logs.outliers", None, "must be one of"),
]


@pytest.mark.parametrize("options, field, flag, what", BAD, ids=[b[1] + "-" + str(i) for i, b in enumerate(BAD)])
def test_a_bad_config_names_the_field(options, field, flag, what, tmp_path):
    config = RunConfig.from_options(robot="ur5", data=[tmp_path / "a.npz"], **options)
    with pytest.raises(OptionError) as e:
        check_run_config(config)
    msg = str(e.value)
    assert f"`{field}`" in msg and what in msg, msg
    assert "--" not in msg, msg  # a field, never a CLI flag
    assert field in [f for f, _ in e.value.settings]


@pytest.mark.parametrize("options, field, flag, what", [b for b in BAD if b[2] is not None],
                         ids=[b[2] for b in BAD if b[2] is not None])
def test_the_command_names_the_flag_for_the_same_mistake(options, field, flag, what, tmp_path):
    args = []
    for k, v in options.items():
        for x in (v if isinstance(v, tuple) else (v,)):
            args += [f"--{k.replace('_', '-')}", str(x)]
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / "a.npz"), *args,
                                 "--out", str(tmp_path / "o")])
    assert r.exit_code == 2, r.output
    assert flag in r.output and what in r.output and f"`{field}`" not in r.output, r.output
    assert not (tmp_path / "o").exists()


def test_a_good_config_gives_the_friction_law_settings(tmp_path):
    base = dict(robot="ur5", data=[tmp_path / "a.npz"])
    assert check_run_config(RunConfig.from_options(**base)) == ("auto", "auto")
    assert check_run_config(RunConfig.from_options(**base, coulomb_smoothing="0.02", stribeck_velocity=0.1)) == (0.02, 0.1)
    with pytest.raises(OptionError, match="`model.robot`"):
        check_run_config(RunConfig.from_options(data=[tmp_path / "a.npz"]))
    with pytest.raises(OptionError, match="`logs.data`"):
        check_run_config(RunConfig.from_options(robot="ur5"))


def test_auto_or_number():
    assert auto_or_number("f", " AUTO ") == "auto" and auto_or_number("f", "0") == 0.0
    with pytest.raises(OptionError, match="`f` must be a finite number > 0"):
        auto_or_number("f", 0, positive=True)
    for bad in ("inf", "-0.5", "x"):
        with pytest.raises(OptionError, match="`f`"):
            auto_or_number("f", bad)
