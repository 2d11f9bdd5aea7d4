"""report.html: every section present, values escaped, figures embedded."""

from __future__ import annotations

import base64

from sensorless.report import render_html_report, write_html_report


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
    (tmp_path / "result.json").write_text(__import__("json").dumps(_doc()))
    (tmp_path / "torques.png").write_bytes(png)
    out = write_html_report(tmp_path)
    assert out.name == "report.html" and base64.b64encode(png).decode() in out.read_text()
