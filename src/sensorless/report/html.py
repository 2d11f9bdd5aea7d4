"""One self-contained HTML page per ``identify`` run (``report.html``).

Built from the run's ``result.json`` document and the PNG figures of the output directory
(embedded as base64: the page is one file that works offline): a summary, the per-body table
(mass, CoM, inertia: prior, identified, verdict; :mod:`.html_bodies`), the joint terms,
per-joint metrics (training and each held-out log; NRMSE in percent, as the CLI prints it),
the figures (``friction.png``, ``torques.png``, …; click one to see it at full size), the
identifiability (rank, condition number, each base parameter and what it combines), physical
consistency, warnings and the settings as a key/value table. Plain string templating with
``html.escape`` on every value; no dependency, no script or style from the network.
"""

from __future__ import annotations

import base64
from pathlib import Path

from ..io import atomic_write_text
from .html_bodies import bodies_table, joint_terms_table
from .html_format import esc, is_number, num, pct

__all__ = ["write_html_report", "render_html_report", "metrics_html", "page"]

_CSS = """body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1180px;color:#222;padding:0 1em}
h1{font-size:1.5em;margin-bottom:.2em}h2{font-size:1.15em;border-bottom:1px solid #ccc;margin-top:1.6em}
nav{font-size:.9em;color:#555}nav a{margin-right:.8em}
table{border-collapse:collapse;margin:.5em 0;font-size:.9em}td,th{border:1px solid #ccc;padding:2px 7px;text-align:right}
th{background:#f3f3f3}th[colspan]{text-align:center}td.l,th.l{text-align:left}th.body{background:#eef2f7;vertical-align:top}
.ok{color:#187a2f}.bad{color:#b00020;font-weight:bold}.legend{font-size:.85em;color:#444}
.warn{background:#fff6d6;border-left:4px solid #e0a800;padding:4px 8px;margin:4px 0}
.badge{display:inline-block;padding:0 .5em;border-radius:.6em;font-weight:600;font-size:.9em}
.badge.v-data{background:#cdebd3;color:#145c26}.badge.v-prior{background:#ffe9b0;color:#6b4700}
.badge.v-undetermined{background:#f6c6cc;color:#8a0017}
tr.v-data td.val{font-weight:600}tr.v-prior td{background:#fffaf0}tr.v-undetermined td{background:#fdf0f1}
tr#total th,tr#total td{border-top:2px solid #888}
td.expr{font-family:ui-monospace,monospace;font-size:.85em;max-width:720px}
tr.poor td{background:#fdf0f1}
img{max-width:100%;border:1px solid #ddd;cursor:zoom-in}img.zoom{max-width:none;cursor:zoom-out}
.fig{overflow:auto}code{font-size:.9em}"""
_ZOOM = ("<script>document.querySelectorAll('img').forEach(function(i){i.addEventListener('click',"
         "function(){i.classList.toggle('zoom')})})</script>")


def _kv(rows: list[tuple[str, str]], cls: str = "kv") -> str:
    """A key/value table; values are already HTML."""
    return f"<table class={cls}>" + "".join(f"<tr><th class=l>{esc(k)}</th><td class=l>{v}</td></tr>" for k, v in rows) + "</table>"


def metrics_html(columns: dict[str, dict]) -> str:
    """Rows = joints; per model (a ``TorqueMetrics.to_dict()`` document) RMSE [N·m] and NRMSE [%]."""
    cols = {name: doc for name, doc in columns.items() if doc and "per_joint" in doc}
    if not cols:
        return "<p>no metrics</p>"
    joints = list(next(iter(cols.values()))["per_joint"])
    head1 = "".join(f"<th colspan=2>{esc(n)}</th>" for n in cols)
    head2 = "<th>RMSE [N·m]</th><th>NRMSE [%]</th>" * len(cols)
    rows = []
    for j in joints:
        cells = []
        for doc in cols.values():
            e = doc["per_joint"].get(j, {})
            cells.append(f"<td>{num(e.get('rmse'))}</td>"
                         + (f"<td title='{esc(e.get('note', ''))}'>at rest" + (f", bias {num(e['bias'])}" if e.get("bias") is not None else "")
                            + "</td>" if e.get("static") else f"<td>{pct(e.get('nrmse'))}</td>"))
        rows.append(f"<tr><td class=l>{esc(j)}</td>{''.join(cells)}</tr>")
    means = "".join(f"<td>{num(d.get('mean_rmse'))}</td><td>{pct(d.get('mean_nrmse'))}</td>" for d in cols.values())
    return (f"<table><tr><th class=l rowspan=2>joint</th>{head1}</tr><tr>{head2}</tr>{''.join(rows)}"
            f"<tr><th class=l>mean</th>{means}</tr></table>"
            "<p class=legend>NRMSE = RMSE / the joint's measured torque range. At rest: the range is noise, see RMSE.</p>")


def _held_out_columns(cols: dict, method: str) -> dict:
    """CAD, the OLS baseline, other models, the run's own model last, labelled as the CLI's tables."""
    order = sorted(cols, key=lambda k: (k != "cad", k != "ols", k == method, k))
    return {("CAD" if k == "cad" else k.upper()): cols[k] for k in order}


def _summary(doc: dict) -> str:
    d = doc.get("diagnostics") or {}
    method = doc.get("method", "")
    robot = doc.get("robot") or {}
    rows = [("method", esc(doc.get("method", "?")))]
    if isinstance(robot, dict):
        rows.append(("robot", esc(robot.get("name", "?")) + (f" <small>({esc(robot['source'])})</small>" if robot.get("source") else "")))
        if is_number(robot.get("total_mass")):
            rows.append(("model total mass", f"{num(robot['total_mass'])} kg"))
    for key, label in (("n_samples", "training samples"), ("n_standard", "standard parameters"), ("rank", "base parameters (rank)"),
                       ("condition_number", "condition number")):
        if d.get(key) is not None:
            rows.append((label, num(d[key])))
    if "lmi" in d:
        rows.append(("LMI solver", f"{esc(d['lmi'].get('solver'))} ({esc(d['lmi'].get('status'))})"))
    if d.get("gamma") is not None:
        g = d.get("gamma_guard") or {}
        rows.append(("γ (prior weight)", num(d["gamma"]) + (f" <small>(raised from {num(g.get('gamma_cv'))} by the guard)</small>"
                                                          if g.get("applied") else "")))
    tm = doc.get("train_metrics") or {}
    if tm.get("mean_nrmse") is not None:
        rows.append(("training mean NRMSE", f"{pct(tm['mean_nrmse'])} %"))
    blocked = doc.get("blocked_held_out")
    if isinstance(blocked, dict) and blocked.get("mean_nrmse") is not None:
        rows.append((f"blocked held-out mean NRMSE ({blocked.get('blocks')} time blocks of the training logs)",
                     f"{pct(blocked['mean_nrmse'])} %"))
    for log, cols in (doc.get("validation") or {}).items():
        ms = _held_out_columns(cols, method)
        rows.append((f"held-out mean NRMSE, {Path(log).name}",
                     ", ".join(f"{esc(n)} {pct(m.get('mean_nrmse'))} %" for n, m in ms.items() if isinstance(m, dict))))
    counts = (d.get("verdicts") or {}).get("counts")
    if counts:
        rows.append(("body masses", ", ".join(f"{counts.get(k, 0)} {k}" for k in ("data", "prior", "undetermined"))))
    pc = doc.get("physical_consistency") or {}
    if pc:
        bad = pc.get("inconsistent_bodies") or []
        rows.append(("physical consistency", f"<span class=bad>{len(bad)} of {pc.get('n_bodies')} bodies inconsistent</span>"
                     if bad else f"<span class=ok>all {pc.get('n_bodies')} bodies consistent</span>"))
    return _kv(rows)


def _pretty_expr(expr: str) -> str:
    return esc(expr.replace("-1*", "−").replace(" - ", " − ").replace("*", "·"))


def _identifiability(doc: dict) -> str:
    """Rank, condition number and one row per base parameter: what it combines, its value, its
    relative standard deviation (%) and whether the data determine it, counted by the verdicts' rule
    (relative std from the data alone at most :data:`~sensorless.identification.verdicts.DATA_REL_STD`),
    and among those not determined, the poorly identified ones (their uncertainty also moves the torques)."""
    from ..identification.verdicts import DATA_REL_STD

    d = doc.get("diagnostics") or {}
    bp = doc.get("base_parameters") or {}
    poor = d.get("poorly_identified") or []
    poor_names = {p.get("base_parameter") if isinstance(p, dict) else str(p) for p in poor}
    names, exprs = bp.get("independent") or [], bp.get("expressions") or []
    vals, rel = bp.get("values") or [], d.get("base_relative_std") or []
    undetermined = [i for i in range(len(rel)) if rel[i] is None or not is_number(rel[i]) or rel[i] > DATA_REL_STD]
    out = [f"<h2 id=identifiability>Identifiability</h2><p>rank <b>{num(d.get('rank'))}</b> of {num(d.get('n_standard'))} "
           f"standard parameters (the other directions are invisible in joint torques, or unexcited by this log); "
           f"condition number <b>{num(d.get('condition_number'))}</b>; <b>{len(undetermined)}</b> of {len(rel)} base "
           f"parameter(s) not determined by the data (relative standard deviation from the data alone above "
           f"{100 * DATA_REL_STD:.0f} % or none: the rule of the verdicts), <b>{len(poor)}</b> of them poorly "
           "identified (above 100 % and a torque effect above the noise).</p>"]
    if not exprs:
        for p in poor[:40]:
            out.append(f"<div class=warn>{esc(p.get('base_parameter') if isinstance(p, dict) else p)}</div>")
        return "".join(out)
    rows = []
    for i, expr in enumerate(exprs):
        name = names[i] if i < len(names) else ""
        alone = expr.strip() == name
        r = rel[i] if i < len(rel) else None
        cls = " class=poor" if expr in poor_names else ""
        shown = ("—" if r is None or not is_number(r) else "&gt; 1000" if r > 10 else pct(r))
        state = ("<span class=bad>poor</span>" if cls else "not by the data" if i in undetermined else "data")
        rows.append(f"<tr{cls}><td>{i + 1}</td><td class=l>{esc(name)}</td>"
                    f"<td class='l expr'>{'<i>itself</i>' if alone else _pretty_expr(expr)}</td>"
                    f"<td>{num(vals[i] if i < len(vals) else None)}</td><td>{shown}</td>"
                    f"<td class=l>{state}</td></tr>")
    out.append("<p class=legend>Each base parameter is the identifiable combination of standard parameters shown "
               "(<i>itself</i>: identifiable alone); rel. std = its standard deviation from the data / |value|.</p>"
               "<table><tr><th>#</th><th class=l>base parameter</th><th class=l>combines</th><th>value</th>"
               "<th>rel. std [%]</th><th class=l>determined</th></tr>" + "".join(rows) + "</table>")
    return "".join(out)


def _consistency(doc: dict) -> str:
    """Per body from the LMI report: mass, principal moments about the CoM and the margins."""
    pc = doc.get("physical_consistency") or {}
    bodies = ((doc.get("diagnostics") or {}).get("lmi") or {}).get("bodies") or []
    if not pc and not bodies:
        return ""
    bad = pc.get("inconsistent_bodies") or []
    head = (f"<p class=bad>{len(bad)} of {pc.get('n_bodies')} bodies are not physically consistent: {esc(', '.join(bad))}</p>"
            if bad else f"<p class=ok>all {pc.get('n_bodies', len(bodies))} bodies are physically consistent</p>")
    ok = {True: "<span class=ok>yes</span>", False: "<span class=bad>no</span>"}
    rows = "".join(
        f"<tr><td class=l>{esc(b.get('name'))}</td><td>{num(b.get('mass'))}</td>"
        f"<td>{', '.join(num(x) for x in b.get('principal_moments') or [])}</td>"
        f"<td>{num(b.get('min_eig_pseudo_inertia'), 3)}</td><td>{num(b.get('ellipsoid_margin'), 3)}</td>"
        f"<td class=l>{ok[bool(b.get('consistent'))]}{' (projected)' if b.get('projected') else ''}</td></tr>" for b in bodies)
    table = ("<table><tr><th class=l>body</th><th>m [kg]</th><th>principal moments about the CoM [kg·m²]</th>"
             "<th>λ<sub>min</sub> pseudo-inertia</th><th>ellipsoid margin</th><th class=l>consistent</th></tr>"
             + rows + "</table>") if bodies else ""
    return "<h2 id=consistency>Physical consistency</h2>" + head + table


def _floating_base(doc: dict) -> str:
    fb = doc.get("floating_base")
    if not fb:
        return ""
    rows = []
    mp = doc.get("mass_properties") or {}
    if is_number(mp.get("total_mass")):
        rows.append(("identified total mass", f"{num(mp['total_mass'])} kg (model file {num(mp.get('urdf_total_mass'))} kg)"))
    for k, t in enumerate(fb.get("train") or []):
        bw, cc, c = t.get("base_wrench") or {}, t.get("com_cop") or {}, t.get("contacts") or {}
        rows.append((f"training log {k + 1}: base-wrench RMSE (world)",
                     f"{num(bw.get('force_rmse_norm'), 3)} N, {num(bw.get('moment_rmse_norm'), 3)} N·m"))
        if cc.get("n_samples") and is_number(cc.get("distance_mean")):
            rows.append((f"training log {k + 1}: CoM–CoP (standing)", f"{num(1e3 * cc['distance_mean'], 3)} mm"))
        if c.get("fraction"):
            rows.append((f"training log {k + 1}: in contact", ", ".join(f"{esc(f)} {pct(v)} %" for f, v in c["fraction"].items())))
    return "<h2>Floating base</h2>" + _kv(rows)


def _leaf(v) -> str:
    if isinstance(v, dict):
        return ", ".join(f"{esc(k)} {_leaf(x)}" for k, x in v.items()) or "{}"
    if isinstance(v, (list, tuple)):
        return ", ".join(_leaf(x) for x in v) or "—"
    if isinstance(v, bool) or v is None:
        return esc({True: "yes", False: "no", None: "—"}[v])
    return num(v, 6) if is_number(v) else esc(v)


def _flatten(value, prefix: str = "") -> list[tuple[str, str]]:
    """Nested settings as (dotted key, readable value): a dict of scalars stays on one row."""
    if isinstance(value, dict) and (not prefix or any(isinstance(v, (dict, list)) for v in value.values())):
        out = []
        for k, v in value.items():
            out += _flatten(v, f"{prefix}.{k}" if prefix else str(k))
        return out
    return [(prefix, _leaf(value))]


def _settings(doc: dict) -> str:
    rows = _flatten(_settings_view(doc.get("settings") or {}))
    versions = doc.get("versions") or {}
    if versions:
        rows.append(("versions", _leaf(versions)))
    return ("<h2 id=settings>Settings</h2><p class=legend>As recorded in result.json (<code>settings</code>); long "
            "numeric lists are summarised here and kept whole in the file.</p>" + _kv(rows, "settings"))


def _gist(text: object) -> str:
    """A warning without the settings it names (`field` in the library's words, --flag in the command's)."""
    import re

    return " ".join(re.sub(r"`[^`]*`|--[\w-]+(=\S+)?", "", str(text)).split())


def render_html_report(doc: dict, figures: dict[str, bytes] | None = None, title: str | None = None) -> str:
    """The page for a result document (``result.json`` as written by ``identify``)."""
    d = doc.get("diagnostics") or {}
    robot = doc.get("robot") or {}
    rname = robot.get("name", "robot") if isinstance(robot, dict) else robot
    method = doc.get("method", "?")
    parts = [f"<h1>{esc(title or f'sensorless identify: {rname}, method {method}')}</h1>",
             "<nav><a href=#summary>summary</a><a href=#bodies>bodies</a><a href=#joints>joint terms</a>"
             "<a href=#metrics>metrics</a><a href=#figures>figures</a><a href=#identifiability>identifiability</a>"
             "<a href=#consistency>consistency</a><a href=#settings>settings</a></nav>",
             "<h2 id=summary>Summary</h2>" + _summary(doc)]
    warns = list(d.get("warnings") or [])
    if doc.get("urdf_error"):
        warns.append(f"no URDF: {doc['urdf_error']}")
    if doc.get("terminal_warnings") is not None:  # everything the terminal said (in its words), once
        said = " ".join(_gist(w) for w in doc["terminal_warnings"])
        warns = list(doc["terminal_warnings"]) + [w for w in warns if _gist(w)[:60] not in said]
    if warns:
        parts.append("<h2>Warnings</h2>" + "".join(f"<div class=warn>{esc(w)}</div>" for w in warns))
    parts += [bodies_table(doc), joint_terms_table(doc)]
    parts.append("<h2 id=metrics>Per-joint metrics (training)</h2>"
                 + metrics_html({method.upper(): doc.get("train_metrics")}))
    for log, cols in (doc.get("validation") or {}).items():
        parts.append(f"<h2>Held-out: {esc(Path(log).name)}</h2>" + metrics_html(_held_out_columns(cols, method)))
    blocked = doc.get("blocked_held_out")
    if isinstance(blocked, dict):
        parts.append(f"<h2>Blocked held-out (training logs)</h2><p class=legend>{esc(blocked.get('label', ''))}</p>"
                     + metrics_html({method.upper(): blocked}))
    parts.append(_floating_base(doc))
    if figures:
        parts.append("<h2 id=figures>Figures</h2>")
    for name, png in _figure_order(figures or {}):
        b64 = base64.b64encode(png).decode("ascii")
        parts.append(f"<h3>{esc(name)}</h3><div class=fig><img alt='{esc(name)}' src='data:image/png;base64,{b64}'></div>")
    parts += [_identifiability(doc), _consistency(doc)]
    if doc.get("urdf"):
        uv = doc.get("urdf_values") or {}
        parts.append(f"<h2>Model</h2><p>URDF: <code>{esc(doc['urdf'])}</code> ({esc(doc.get('urdf_export', ''))})"
                     + (f"; inertials: {esc(uv.get('values'))} values" if uv.get("values") else "")
                     + (f"; {esc(uv['fallback'])}" if uv.get("fallback") else "") + "</p>")
    parts.append(_settings(doc))
    return page(f"{rname} identification", parts)


def page(title: str, parts: list[str]) -> str:
    """A self-contained page: ``parts`` (HTML) with the report's style and figure zoom."""
    body = "\n".join(p for p in parts if p)
    return (f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>{esc(title)}</title>"
            f"<style>{_CSS}</style></head><body>\n{body}\n{_ZOOM}</body></html>\n")


def _figure_order(figures: dict[str, bytes]) -> list[tuple[str, bytes]]:
    """Friction first, then torques (per-limb files included), then the rest, each in name order."""
    def rank(name: str) -> int:
        return 0 if name.startswith("friction") else 1 if name.startswith("torques") else 2
    return sorted(figures.items(), key=lambda kv: (rank(kv[0]), kv[0]))


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
            return f"{len(value)} values in [{min(value):.4g}, {max(value):.4g}]"
        return [_settings_view(v, depth + 1) for v in value]
    return value
