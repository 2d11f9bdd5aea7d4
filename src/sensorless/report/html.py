"""One self-contained HTML page per ``identify`` run (``report.html``).

Built from the run's ``result.json`` document and the PNG figures of the output directory
(embedded as base64, so the page is one file): per-joint metrics (training and each
held-out log), physical consistency, identifiability (rank, condition number, poorly
identified parameters), warnings and the settings. Plain string templating with
``html.escape`` on every value; no dependency.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path
from typing import Any

from ..io import atomic_write_text

__all__ = ["write_html_report", "render_html_report"]

_CSS = """body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1100px;color:#222}
h1{font-size:1.5em}h2{font-size:1.15em;border-bottom:1px solid #ccc;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f3f3f3}td.l,th.l{text-align:left}.ok{color:#187a2f}.bad{color:#b00020;font-weight:bold}
.warn{background:#fff6d6;border-left:4px solid #e0a800;padding:4px 8px;margin:4px 0}
img{max-width:100%;border:1px solid #ddd}pre{background:#f7f7f7;padding:8px;overflow:auto;font-size:.85em}"""


def _e(x: Any) -> str:
    return html.escape(str(x))


def _num(x: Any) -> str:
    if x is None:
        return "—"
    if isinstance(x, dict):
        return ", ".join(f"{_e(k)} {_num(v)}" for k, v in x.items())
    return f"{x:.4g}" if isinstance(x, (int, float)) and not isinstance(x, bool) else _e(x)


def _metrics_table(columns: dict[str, dict]) -> str:
    """Rows = joints, columns = (model, metric) from TorqueMetrics.to_dict() documents."""
    cols = [(name, m) for name, doc in columns.items() for m in ("rmse", "nrmse") if doc and "per_joint" in doc]
    if not cols:
        return "<p>no metrics</p>"
    joints = list(next(d for d in columns.values() if d and "per_joint" in d)["per_joint"])
    head = "".join(f"<th>{_e(n)} {m.upper()}</th>" for n, m in cols)
    rows = "".join(
        f"<tr><td class=l>{_e(j)}</td>" + "".join(f"<td>{_num(columns[n]['per_joint'].get(j, {}).get(m, ''))}</td>"
                                              for n, m in cols) + "</tr>" for j in joints)
    means = "".join(f"<td>{_num(columns[n].get('mean_' + m, ''))}</td>" for n, m in cols)
    return f"<table><tr><th class=l>joint</th>{head}</tr>{rows}<tr><th class=l>mean</th>{means}</tr></table>"


def _verdict_table(v: dict | None) -> str:
    """Per body: mass, its prior, data-alone std, prior share and verdict (diagnostics.verdicts)."""
    if not v or not v.get("bodies"):
        return ""
    rows = []
    for body, e in v["bodies"].items():
        m = e["mass"]
        rest = [x["verdict"] for q, x in e.items() if q != "mass"]
        shown = _num(m["value"]) if m["verdict"] == "data" else "—"
        rows.append(f"<tr><td class=l>{_e(body)}</td><td>{shown}</td><td>{_num(m['prior'])}</td>"
                    f"<td>{'∞' if m['std_data'] is None else _num(m['std_data'])}</td>"
                    f"<td>{'' if m['prior_share'] is None else _num(m['prior_share'])}</td>"
                    f"<td class=l>{_e(m['verdict'])}</td><td class=l>"
                    + _e(", ".join(f"{n} {rest.count(n)}" for n in ("data", "prior", "undetermined") if rest.count(n)))
                    + "</td></tr>")
    return ("<h2>Verdicts (what the data determine)</h2><table><tr><th class=l>body</th><th>m [kg]</th>"
            "<th>prior m</th><th>std (data alone)</th><th>prior share</th><th class=l>verdict</th>"
            "<th class=l>CoM / inertia</th></tr>" + "".join(rows) + "</table>")


def render_html_report(doc: dict, figures: dict[str, bytes] | None = None, title: str | None = None) -> str:
    """The page for a result document (``result.json`` as written by ``identify``)."""
    d = doc.get("diagnostics", {})
    robot = doc.get("robot", {})
    rname = robot.get("name", "robot") if isinstance(robot, dict) else robot
    method = doc.get("method", "?")
    parts = [f"<h1>{_e(title or f'sensorless identify: {rname}, method {method}')}</h1>"]
    summary = {"method": doc.get("method"), "samples": d.get("n_samples"), "rank": d.get("rank"),
               "parameters": d.get("n_standard"), "condition number": d.get("condition_number"),
               "residual σ": d.get("residual_sigma")}
    if "lmi" in d:
        summary.update({"LMI solver": d["lmi"].get("solver"), "LMI status": d["lmi"].get("status"), "γ": d.get("gamma")})
    parts.append("<table>" + "".join(f"<tr><th class=l>{_e(k)}</th><td>{_num(v)}</td></tr>"
                                     for k, v in summary.items() if v is not None) + "</table>")
    warns = list(d.get("warnings") or [])
    if doc.get("urdf_error"):
        warns.append(f"no URDF: {doc['urdf_error']}")
    parts.append("<h2>Warnings</h2>" + ("".join(f"<div class=warn>{_e(w)}</div>" for w in warns) or "<p class=ok>none</p>"))
    parts.append("<h2>Per-joint metrics (training)</h2>" + _metrics_table({doc.get("method", "model"): doc.get("train_metrics")}))
    for log, cols in (doc.get("validation") or {}).items():
        parts.append(f"<h2>Held-out: {_e(Path(log).name)}</h2>" + _metrics_table(cols))
    for name, png in (figures or {}).items():
        b64 = base64.b64encode(png).decode("ascii")
        parts.append(f"<h2>{_e(name)}</h2><img alt='{_e(name)}' src='data:image/png;base64,{b64}'>")
    pc = doc.get("physical_consistency") or {}
    if pc:
        bad = pc.get("inconsistent_bodies") or []
        status = (f"<p class=bad>{len(bad)} of {pc.get('n_bodies')} bodies are not physically consistent: "
                  f"{_e(', '.join(bad))}</p>" if bad else f"<p class=ok>all {pc.get('n_bodies')} bodies are physically consistent</p>")
        parts.append("<h2>Physical consistency</h2>" + status)
    parts.append("<h2>Identifiability</h2>")
    poor = d.get("poorly_identified") or []
    parts.append(f"<p>rank {_num(d.get('rank'))} of {_num(d.get('n_standard'))} standard parameters; "
                 f"condition number {_num(d.get('condition_number'))}; {len(poor)} poorly identified base parameter(s)</p>")
    if poor:
        parts.append("<table><tr><th class=l>base parameter</th></tr>" + "".join(
            f"<tr><td class=l>{_e(p if not isinstance(p, dict) else json.dumps(p))}</td></tr>" for p in poor[:40]) + "</table>")
    parts.append(_verdict_table(d.get("verdicts")))
    if doc.get("urdf"):
        parts.append(f"<h2>Model</h2><p>URDF: {_e(doc['urdf'])} — {_e(doc.get('urdf_export', ''))}</p>")
    parts.append("<h2>Settings</h2><pre>" + _e(json.dumps(_settings_view(doc.get("settings", {})), indent=1,
                                                         default=str)) + "</pre>")
    body = "\n".join(parts)
    return (f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>{_e(rname)} identification</title>"
            f"<style>{_CSS}</style></head><body>\n{body}\n</body></html>\n")


def write_html_report(out_dir: str | Path, doc: dict | None = None) -> Path:
    """``out_dir/report.html`` from ``doc`` (default: ``out_dir/result.json``) and the PNGs in ``out_dir``."""
    out_dir = Path(out_dir)
    if doc is None:
        from ..identification.artifact import read_result

        doc = read_result(out_dir)
    figures = {p.stem.replace("_", " "): p.read_bytes() for p in sorted(out_dir.glob("*.png"))}
    return atomic_write_text(out_dir / "report.html", render_html_report(doc, figures))


def _settings_view(value, depth: int = 0):
    """The settings for reading: a long list of numbers (a search grid, per-candidate scores) is
    summarised as its range and length (result.json holds it whole), nothing is cut mid-way."""
    if isinstance(value, dict):
        return {k: _settings_view(v, depth + 1) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        if len(value) > 12 and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value):
            return f"{len(value)} values in [{min(value):.4g}, {max(value):.4g}] (whole in result.json)"
        return [_settings_view(v, depth + 1) for v in value]
    return value
