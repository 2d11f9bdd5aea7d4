"""report.html: every section present, values escaped, figures embedded; on a real `identify --method lmi`
run, the per-body and joint-term tables hold each quantity's prior, identified value and verdict from
result.json, metrics are in percent, no raw JSON is dumped; the page renders in headless Chromium."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.report import render_html_report, write_html_report
from sensorless.report.html_format import num, pct


def _doc():
    m = {"per_joint": {"j<1>": {"rmse": 0.5, "nrmse": 0.05}}, "mean_rmse": 0.5, "mean_nrmse": 0.05}
    return {"method": "lmi", "robot": {"name": "arm"}, "train_metrics": m,
            "validation": {"/x/test.npz": {"lmi": m, "cad": m}},
            "diagnostics": {"rank": 3, "n_standard": 10, "condition_number": 12.5, "n_samples": 100,
                            "warnings": ["joint j<1> barely moves"], "poorly_identified": ["b0"]},
            "physical_consistency": {"inconsistent_bodies": ["link2"], "n_bodies": 2},
            "settings": {"data": ["a.npz"]}, "urdf": "model.urdf", "urdf_export": "patched x.urdf"}


def test_sections_escaping_and_figures(tmp_path):
    png = b"\x89PNG\r\n\x1a\nfake"
    page = render_html_report(_doc(), {"torques": png})
    for needle in ("Warnings", "Per-joint metrics", "Held-out: test.npz", "Physical consistency", "Identifiability",
                   "Settings", "1 of 2 bodies are not physically consistent: link2", "patched x.urdf"):
        assert needle in page, needle
    assert "j&lt;1&gt;" in page and "j<1>" not in page  # joint names are escaped
    assert base64.b64encode(png).decode() in page
    assert ">5.00<" in page and ">0.05<" not in page  # NRMSE 0.05 is shown as 5.00 %
    (tmp_path / "result.json").write_text(json.dumps(_doc()))
    (tmp_path / "torques.png").write_bytes(png)
    out = write_html_report(tmp_path)
    assert out.name == "report.html" and base64.b64encode(png).decode() in out.read_text()


class _Tables(HTMLParser):
    """Every <table> as rows of cells ``(text, tag, attrs, inner html classes)``, plus the visible text."""

    def __init__(self):
        super().__init__()
        self.tables: list[dict] = []
        self.text: list[str] = []
        self.imgs: list[str] = []
        self._cell = None
        self._skip = 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag in ("script", "style"):
            self._skip += 1
        elif tag == "table":
            self.tables.append({"class": a.get("class", ""), "rows": []})
        elif tag == "tr" and self.tables:
            self.tables[-1]["rows"].append({"id": a.get("id"), "class": a.get("class", ""), "cells": []})
        elif tag in ("td", "th") and self.tables:
            self._cell = {"tag": tag, "class": a.get("class", ""), "text": "", "badges": []}
            self.tables[-1]["rows"][-1]["cells"].append(self._cell)
        elif tag == "span" and self._cell is not None and "badge" in (a.get("class") or ""):
            self._cell["badges"].append(a["class"])
        elif tag == "img":
            self.imgs.append(a.get("src", ""))

    def handle_endtag(self, tag):
        if tag in ("script", "style"):
            self._skip -= 1
        elif tag in ("td", "th"):
            self._cell = None

    def handle_data(self, data):
        if self._skip:
            return
        self.text.append(data)
        if self._cell is not None:
            self._cell["text"] += data


def _texts(row) -> list[str]:
    return [c["text"].strip() for c in row["cells"]]


@pytest.fixture(scope="module")
def lmi_run(tmp_path_factory):
    """`identify --method lmi --validate` on short simulated UR5 logs (a perturbed robot with friction)."""
    from sensorless.cli import app
    from sensorless.data import write_npz
    from sensorless.excitation import random_fourier
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    d = tmp_path_factory.mktemp("html")
    robot = load_robot("ur5")
    truth = perturbed_truth(robot, rng=0)
    for name, seed, dur in (("train", 1, 5.0), ("test", 3, 3.0)):
        log = synthetic_trajectory(truth, random_fourier(robot, rng=seed).sample(100, dur), noise_std=0.05, rng=seed + 1)
        write_npz(log, d / f"{name}.npz")
    res = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(d / "train.npz"), "--validate",
                                   str(d / "test.npz"), "--method", "lmi", "--out", str(d / "run")])
    assert res.exit_code == 0, res.output
    return d / "run"


def test_report_of_an_lmi_run_holds_bodies_verdicts_percent_and_no_raw_json(lmi_run):
    doc = json.loads((lmi_run / "result.json").read_text())
    page = (lmi_run / "report.html").read_text()
    p = _Tables()
    p.feed(page)
    v = doc["diagnostics"]["verdicts"]
    body_t, joint_t = [t for t in p.tables if t["class"] == "verdicts"]
    head = _texts(body_t["rows"][0])
    col = {h: k for k, h in enumerate(head)}
    assert {"prior", "identified", "σ", "prior share [%]", "verdict"} <= set(col)

    # per body: 10 rows (m, c_x..c_z, six inertia entries), the body cell names its link; then the total mass
    rows = body_t["rows"][1:]
    assert len(rows) == 10 * len(v["bodies"]) + 1
    seen = set()
    for k, (body, quantities) in enumerate(v["bodies"].items()):
        block = rows[10 * k: 10 * k + 10]
        link = doc["parameter_links"][f"{body}.m"].split(".")[0]
        assert link in block[0]["cells"][0]["text"] and body in block[0]["cells"][0]["text"]
        for row, key in zip(block, ("mass", "com_x", "com_y", "com_z", "ixx", "ixy", "iyy", "ixz", "iyz", "izz")):
            e = quantities[key]
            cells = _texts(row)[-7:]  # unit, prior, identified, ±, prior share, verdict (the first row also has the body)
            unit, prior, ident, std, share, verdict = cells[-6], cells[-5], cells[-4], cells[-3], cells[-2], cells[-1]
            assert unit == {"mass": "kg"}.get(key, "m" if key.startswith("com") else "kg·m²")
            assert prior == num(e["prior"]) and verdict == e["verdict"]
            assert ident == ("—" if e["verdict"] == "undetermined" else num(e["value"]))
            sd = e.get("std", e["std_data"])  # the verdict's σ; the linear one too where it is > 2× narrower
            assert std.startswith("—" if sd is None else num(sd, 2))
            assert ("(linear" in std) == bool(e.get("linear_too_narrow") and e["std_data"] is not None)
            assert share == pct(e["prior_share"]).replace("&lt;", "<")
            assert row["cells"][-1]["badges"] == [f"badge v-{e['verdict']}"] and row["class"] == f"v-{e['verdict']}"
            seen.add(e["verdict"])
    assert seen >= {"data", "prior"}  # this log determines some quantities and not others: both are flagged
    total = rows[-1]
    assert total["id"] == "total" and _texts(total)[0] == "total mass"
    assert _texts(total)[-1] == v["robot"]["total_mass"]["verdict"]
    assert _texts(total)[3] == num(v["robot"]["total_mass"]["prior"])

    # joint terms: one row per (joint, term) with its verdict
    jrows = joint_t["rows"][1:]
    assert len(jrows) == sum(len(t) for t in v["joints"].values())
    assert [r["cells"][-1]["text"] for r in jrows] == [e["verdict"] for t in v["joints"].values() for e in t.values()]

    # percent everywhere: held-out NRMSE per joint and model as the CLI prints it (2 decimals), never the fraction
    held = next(t for t in p.tables if any("NRMSE [%]" in c["text"] for r in t["rows"][:2] for c in r["cells"])
                and any("CAD" in c["text"] for c in t["rows"][0]["cells"]))
    models = [c["text"] for c in held["rows"][0]["cells"][1:]]
    assert models == ["CAD", "OLS", "LMI"]
    val = next(iter(doc["validation"].values()))
    for r in held["rows"][2:-1]:
        joint, cells = _texts(r)[0], _texts(r)[1:]
        for k, m in enumerate(("cad", "ols", "lmi")):
            x = val[m]["per_joint"][joint]["nrmse"]
            assert cells[2 * k + 1] == f"{100 * x:.2f}"
    assert f"{100 * doc['train_metrics']['mean_nrmse']:.2f} %" in page

    # identifiability: one row per base parameter, naming what it combines
    ident = next(t for t in p.tables if _texts(t["rows"][0])[:3] == ["#", "base parameter", "combines"])
    assert len(ident["rows"]) - 1 == doc["base_parameters"]["rank"] == doc["diagnostics"]["rank"]
    assert [_texts(r)[1] for r in ident["rows"][1:]] == doc["base_parameters"]["independent"]
    combined = [r for r in ident["rows"][1:] if "·" in r["cells"][2]["text"]]
    assert combined  # an arm always has regrouped parameters (e.g. link masses into the links above)

    # settings as key/value rows; long numeric lists summarised; no JSON dump anywhere in the visible text
    text = "".join(p.text)
    settings = next(t for t in p.tables if t["class"] == "settings")
    assert _texts(settings["rows"][0]) == ["method", "lmi"]
    keys = [_texts(r)[0] for r in settings["rows"]]
    assert "regularization" in keys and "data" in keys and any(k.startswith("preprocessing.") for k in keys)
    assert "values in [" in text
    for raw in ('{"', '":', "{'", "':", "[{"):
        assert raw not in text, raw
    assert "<pre" not in page

    # figures embedded (the PNGs of the output folder), nothing fetched from the network
    for name in ("friction.png", "torques.png"):
        assert f"data:image/png;base64,{base64.b64encode((lmi_run / name).read_bytes()).decode()}" in p.imgs
    assert "http://" not in page and "https://" not in page and "<link" not in page


@pytest.fixture(scope="module")
def browser() -> str:
    """A Chromium binary (before the identify run, so a machine without one skips at once)."""
    found = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)
    if found is None:
        pytest.skip("no Chromium binary on PATH (chromium, chromium-browser, google-chrome): apt-get install chromium")
    return found


def test_report_renders_in_headless_chromium(browser, lmi_run, tmp_path):
    from PIL import Image

    shot = tmp_path / "report.png"
    run = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                    "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'profile'}",
                    "--hide-scrollbars", f"--screenshot={shot}", "--window-size=1280,2400",
                    (lmi_run / "report.html").as_uri()], capture_output=True, text=True, timeout=180, check=False)
    assert shot.exists(), f"chromium wrote no screenshot (exit {run.returncode}): {run.stderr[-2000:]}"
    img = np.asarray(Image.open(shot).convert("L"), dtype=float)
    assert img.shape == (2400, 1280)
    # not blank: text, table rules and the verdict badges make a page far from uniform
    assert img.std() > 20.0, img.std()
    rows_with_ink = (img < 200).any(axis=1).mean()
    assert rows_with_ink > 0.5, rows_with_ink  # the tables fill the page, not one line at the top
    rgb = np.asarray(Image.open(shot).convert("RGB"), dtype=int)
    green = (rgb[..., 1] - rgb[..., 0] > 20) & (rgb[..., 1] - rgb[..., 2] > 10)  # 'data' badges
    amber = (rgb[..., 0] - rgb[..., 2] > 60) & (rgb[..., 1] > 180)  # 'prior' badges and rows
    assert green.sum() > 200 and amber.sum() > 200, (green.sum(), amber.sum())
