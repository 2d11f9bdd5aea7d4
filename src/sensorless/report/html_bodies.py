"""report.html: per-body and per-joint-term tables, prior against identified, with each verdict.

Rows come from ``diagnostics.verdicts`` of ``result.json`` (:mod:`sensorless.identification.verdicts`):
``{value, prior, std_data, prior_share, verdict}`` for each body's mass, CoM and six inertia
entries, the total mass and every joint term. A value whose verdict is ``undetermined`` is not
shown (neither the data nor the prior fixed it); ``prior`` values are shown, labelled.
A result without verdicts gets the identified values only, from ``parameters``.
"""

from __future__ import annotations

from .html_format import esc, is_number, num, pct

__all__ = ["VERDICT_LEGEND", "bodies_table", "joint_terms_table", "verdict_cell"]

#: (key in verdicts, label, unit); inertia entries about the body frame origin.
BODY_QUANTITIES = (("mass", "m", "kg"), ("com_x", "c<sub>x</sub>", "m"), ("com_y", "c<sub>y</sub>", "m"),
                   ("com_z", "c<sub>z</sub>", "m"), ("ixx", "I<sub>xx</sub>", "kg·m²"), ("ixy", "I<sub>xy</sub>", "kg·m²"),
                   ("iyy", "I<sub>yy</sub>", "kg·m²"), ("ixz", "I<sub>xz</sub>", "kg·m²"), ("iyz", "I<sub>yz</sub>", "kg·m²"),
                   ("izz", "I<sub>zz</sub>", "kg·m²"))
#: joint terms, units for a revolute joint (prismatic: N, N·s/m, kg).
JOINT_TERMS = {"fv": ("viscous f<sub>v</sub>", "N·m·s/rad"), "fc": ("Coulomb f<sub>c</sub>", "N·m"),
               "stribeck": ("Stribeck f<sub>s</sub> − f<sub>c</sub>", "N·m"), "offset": ("offset", "N·m"),
               "armature": ("armature", "kg·m²")}
_PARAM_KEYS = {"mass": "m", "ixx": "Ixx", "ixy": "Ixy", "iyy": "Iyy", "ixz": "Ixz", "iyz": "Iyz", "izz": "Izz"}

VERDICT_LEGEND = (
    "<p class=legend><span class='badge v-data'>data</span> the log determines the value (its data-alone "
    "standard deviation is small and the prior's share is below 50 %) · <span class='badge v-prior'>prior</span> "
    "the value comes mostly from the prior (the URDF or <code>--prior</code>) · "
    "<span class='badge v-undetermined'>undetermined</span> neither fixes it: the value is not shown. "
    "± = standard deviation from the data alone (—: none, part of the quantity lies where the log's regressor is "
    "blind; the verdict says where the value comes from); "
    "prior share = the part of the value the regulariser pulled from the prior.</p>")

_HEAD = ("<tr><th class=l>{what}</th><th class=l>quantity</th><th class=l>unit</th><th>prior</th><th>identified</th>"
         "<th>σ</th><th>prior share [%]</th><th class=l>verdict</th></tr>")


def verdict_cell(verdict: str | None) -> str:
    if not verdict:
        return "<td class=l>—</td>"
    return f"<td class=l><span class='badge v-{esc(verdict)}'>{esc(verdict)}</span></td>"


def _row(label: str, unit: str, e: dict, lead: str = "", row_id: str = "") -> str:
    v = e.get("verdict")
    value = e.get("value")
    if v == "undetermined":
        shown = f"<td title='not determined (solver value {num(value)})'>—</td>"
    else:
        shown = f"<td class=val>{num(value)}</td>"
    sd = e.get("std", e.get("std_data")) if "std_data" in e else None
    std = ("" if "std_data" not in e else
           f"<span title='no interval from the data alone: the value is the verdict's ({esc(v or '?')})'>—</span>"
           if sd is None else num(sd, 2))
    if e.get("linear_too_narrow") and e.get("std_data") is not None:  # both, where they differ by more than 2×
        std += f" <small title='linear covariance: a lower bound'>(linear {num(e['std_data'], 2)})</small>"
    rid = f" id={row_id}" if row_id else ""
    return (f"<tr{rid} class='v-{esc(v or 'none')}'>{lead}<td class=l>{label}</td><td class=l>{esc(unit)}</td>"
            f"<td>{num(e.get('prior'))}</td>{shown}<td>{std}</td><td>{pct(e.get('prior_share'))}</td>"
            f"{verdict_cell(v)}</tr>")


def _body_name(doc: dict, body: str) -> str:
    link = (doc.get("parameter_links") or {}).get(f"{body}.m", "")
    link = link.rsplit(".", 1)[0] if link else ""
    return esc(link) + f"<br><small>{esc(body)}</small>" if link and link != body else esc(body)


def _from_parameters(doc: dict) -> dict:
    """Per body, identified values only (no verdicts): c = h/m from the first moments."""
    p = doc.get("parameters") or {}
    bodies = (doc.get("robot") or {}).get("bodies") or sorted({k.rsplit(".", 1)[0] for k in p if k.endswith(".m")})
    out = {}
    for b in bodies:
        if f"{b}.m" not in p:
            continue
        m = p[f"{b}.m"]
        e = {q: {"value": p.get(f"{b}.{k}")} for q, k in _PARAM_KEYS.items()}
        for ax in "xyz":
            h = p.get(f"{b}.m{ax}")
            e[f"com_{ax}"] = {"value": h / m if is_number(h) and is_number(m) and m > 0 else None}
        out[b] = e
    return out


def bodies_table(doc: dict) -> str:
    """The per-body table: one row per quantity (mass, CoM, inertia), a total-mass row last."""
    v = (doc.get("diagnostics") or {}).get("verdicts") or {}
    bodies = v.get("bodies") or _from_parameters(doc)
    if not bodies:
        return ""
    bounds = (v.get("active_bounds") or {}).get("bodies") or {}
    rows = []
    for body, e in bodies.items():
        quantities = [q for q in BODY_QUANTITIES if q[0] in e]
        note = f"<br><small class=bad>at bound: {esc(', '.join(bounds[body]))}</small>" if body in bounds else ""
        for k, (key, label, unit) in enumerate(quantities):
            lead = f"<th class='l body' rowspan={len(quantities)}>{_body_name(doc, body)}{note}</th>" if k == 0 else ""
            rows.append(_row(label, unit, e[key], lead))
    total = (v.get("robot") or {}).get("total_mass")
    if total:
        rows.append(_row("m", "kg", total, "<th class='l body'>total mass</th>", row_id="total"))
    counts = v.get("counts")
    all_v = [q.get("verdict") for e in bodies.values() for q in e.values() if isinstance(q, dict) and q.get("verdict")]
    summary = ""
    if all_v:
        summary = (f"<p>{len(bodies)} bodies; of their {len(all_v)} quantities "
                   + ", ".join(f"<b>{all_v.count(x)}</b> {x}" for x in ("data", "prior", "undetermined"))
                   + (f"; body masses: {counts['data']} data, {counts['prior']} prior, {counts['undetermined']} undetermined"
                      if counts else "") + ".</p>")
    else:
        summary = "<p class=warn>This result.json holds no verdicts: identified values only.</p>"
    uv = doc.get("urdf_values") or {}
    if uv.get("prior_mass_bodies"):
        summary += (f"<p class=legend>model.urdf holds the prior's mass for {esc(', '.join(uv['prior_mass_bodies']))} "
                    "(the data do not determine their masses) and reproduces the identified "
                    "dynamics; see Model below.</p>")
    frame = (v.get("settings") or {}).get("inertia")
    frame_note = f"<p class=legend>Inertia: {esc(frame)}. CoM: {esc(v['settings'].get('com', ''))}.</p>" if frame else ""
    return ("<h2 id=bodies>Bodies: prior against identified</h2>" + summary + VERDICT_LEGEND + frame_note
            + "<table class=verdicts>" + _HEAD.format(what="body") + "".join(rows) + "</table>")


def joint_terms_table(doc: dict) -> str:
    """Friction, offset and armature per joint, prior against identified, with verdicts."""
    vd = (doc.get("diagnostics") or {}).get("verdicts") or {}
    v = vd.get("joints")
    if not v:
        terms = doc.get("joint_terms") or {}
        v = {j: {t: {"value": x} for t, x in ts.items()} for j, ts in terms.items() if isinstance(ts, dict)}
    if not v:
        return ""
    zero = set((vd.get("active_bounds") or {}).get("joint_terms_at_zero") or [])
    rows = []
    for joint, terms in v.items():
        keys = list(terms)
        for k, t in enumerate(keys):
            label, unit = JOINT_TERMS.get(t, (esc(t), ""))
            if f"{joint}.{t}" in zero:
                label += " <small class=bad>(held at 0)</small>"
            lead = f"<th class='l body' rowspan={len(keys)}>{esc(joint)}</th>" if k == 0 else ""
            rows.append(_row(label, unit, terms[t], lead))
    return ("<h2 id=joints>Joint terms: prior against identified</h2>"
            "<p class=legend>τ<sub>f</sub> = f<sub>s</sub> tanh(v/w) − (f<sub>s</sub> − f<sub>c</sub>)"
            "(1 − e<sup>−(v/v<sub>s</sub>)²</sup>) sgn v + f<sub>v</sub> v + offset; armature adds I<sub>a</sub> v̇. Units for a revolute joint "
            "(prismatic: N, N·s/m, kg).</p>"
            "<table class=verdicts>" + _HEAD.format(what="joint") + "".join(rows) + "</table>")
