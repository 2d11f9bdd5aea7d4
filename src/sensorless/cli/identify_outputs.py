"""What `sensorless identify` prints: the bodies, the floating-base checks, γ and the summary line."""

from __future__ import annotations

from .console import console, err_console, safe


def print_bodies(result) -> None:
    """Mass per body, named by joint and link (result.json: parameter_links), with its verdict
    (diagnostics.verdicts) and σ (the larger of the linear and the resampled one): the values result.json,
    report.html and model.urdf hold (one presented model); a ``prior`` mass is the prior's, an
    ``undetermined`` one (neither the data's nor the prior's) is shown as '—', never as identified."""
    from rich.table import Table

    from ..identification.result import body_links

    links = body_links(result.robot)
    verdicts = (result.diagnostics.get("verdicts") or {}).get("bodies", {})
    t = Table(title="identified bodies (parameters 'joint.p' in result.json; 'link.p' in parameter_links; "
                    "verdicts in diagnostics.verdicts)")
    for col in ("joint", "link", "m [kg]", "σ [kg]", "CAD m [kg]", "mass from", "CoM / inertia from"):
        t.add_column(col, justify="left" if col in ("joint", "link", "mass from", "CoM / inertia from") else "right")
    pi, pi0 = result.inertial_parameters.reshape(-1, 10), result.robot.inertial_parameters().reshape(-1, 10)
    for k, b in enumerate(result.robot.body_names):
        v = verdicts.get(b)
        if v is None:  # no verdicts (an older result): the value, unlabelled
            t.add_row(safe(b), safe(links.get(b, b)), f"{pi[k, 0]:.3f}", "", f"{pi0[k, 0]:.3f}", "", "")
            continue
        mv = v["mass"]["verdict"]
        std = v["mass"].get("std", v["mass"]["std_data"])
        rest = [v[q]["verdict"] for q in v if q != "mass"]
        lin = v["mass"].get("std_data")
        sig = (f"{std:.2g}" + (f" (linear {lin:.2g})" if v["mass"].get("linear_too_narrow") and lin is not None else "")
               if mv == "data" and std is not None else "")
        t.add_row(safe(b), safe(links.get(b, b)), "—" if mv == "undetermined" else f"{pi[k, 0]:.3f}", sig,
                  f"{pi0[k, 0]:.3f}", mv,
                  ", ".join(f"{n} {rest.count(n)}" for n in ("data", "prior", "undetermined") if rest.count(n)))
    tot = (result.diagnostics.get("verdicts") or {}).get("robot", {}).get("total_mass")
    if tot is not None and tot["verdict"] == "data":  # e.g. a floating base, or a passive rail carrying it all
        std = tot.get("std", tot["std_data"])
        t.add_row("total", "", f"{tot['value']:.3f}", f"{std:.2g}" if std is not None else "", f"{tot['prior']:.3f}",
                  "data", "")
    console.print(t)


def print_floating_base(doc: dict) -> None:
    """The measured-wrench checks of result.json ``floating_base`` (:func:`sensorless.run.validation.floating_base_report`):
    total mass, base-wrench RMSE, CoM–CoP distance, contact flags; warnings where they disagree."""
    fb = doc.get("floating_base")
    if not fb:
        return
    mass = doc.get("mass_properties") or {}
    bw = fb["train"][0].get("base_wrench")  # None on a fixed base (a leg on a passive rail)
    cc = fb["train"][0].get("com_cop") or {"n_samples": 0}
    console.print(
        (f"identified total mass {mass['total_mass']:.3f} kg (model file {mass.get('urdf_total_mass', float('nan')):.3f} "
         "kg)" if "total_mass" in mass else "measured wrenches")
        + (f"; base-wrench RMSE (world) {bw['force_rmse_norm']:.3g} N, {bw['moment_rmse_norm']:.3g} N·m" if bw
           else f"; {fb.get('note', 'no base-wrench rows')}")
        + (f"; CoM–CoP on standing windows {1e3 * cc['distance_mean']:.1f} mm" if cc["n_samples"] else ""))
    for traj_doc in fb["train"]:
        c = traj_doc["contacts"]
        console.print(f"contact flags from the {c['source']}: in contact "
                      + ", ".join(f"{k} {100 * v:.0f} %" for k, v in c["fraction"].items()) + " of the samples",
                      highlight=False)
        missed = {k: v for k, v in c.get("loaded_unflagged", {}).items() if v}
        if missed:
            err_console.print(f"[yellow]warning:[/] the log's contact flags leave out samples whose measured normal "
                              f"force is above the noise: {missed} (those forces are not used)")
    for traj_doc in fb["train"]:
        if (traj_doc.get("com_cop") or {}).get("ok") is False:
            err_console.print(f"[yellow]warning:[/] the identified CoM is {1e3 * traj_doc['com_cop']['distance_mean']:.1f} mm "
                              "from the measured CoP on standing windows (a wrench bias? try --wrench-offset)")


def gamma_note(d: dict) -> str:
    """γ used, with the cross-validation winner and floor when the runaway guard raised it, and active bounds."""
    g = d.get("gamma_guard") or {}
    note = f"γ = {d['gamma']:.3g}"
    if g.get("applied"):
        note += f" (cross-validation chose {g['gamma_cv']:.3g}; raised to the floor {g['floor']:.3g})"
    bounds = ((d.get("verdicts") or {}).get("active_bounds") or {}).get("bodies") or {}
    if bounds:
        note += "; active bounds: " + ", ".join(f"{b} ({'/'.join(v)})" for b, v in list(bounds.items())[:4])
        note += " ..." if len(bounds) > 4 else ""
    return note


def summary_line(result, method: str, skipped: list, out) -> str:
    """The last line of `sensorless identify`: base parameters, γ or condition number, body verdicts."""
    d = result.diagnostics
    extra = (f"{gamma_note(d)}, solver {d['lmi']['solver']} ({d['lmi']['status']}), "
             f"all bodies consistent: {d['lmi']['consistent']}" if method == "lmi"
             else f"condition number {d['condition_number']:.1f}")
    counts = (d.get("verdicts") or {}).get("counts")
    if counts:
        extra += f"; body masses: {counts['data']} from the data, {counts['prior']} prior, {counts['undetermined']} undetermined"
    skip_note = f", {len(skipped)} file(s) skipped (listed in result.json)" if skipped else ""
    return f"{len(result.base.independent)} base parameters, {extra}{skip_note}; wrote {out}/"
