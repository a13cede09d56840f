"""``report.html``: the evidence for the model, one self-contained file (figures inline as base64 PNG).

Figures: the paper's Fig. 2 for every axis (constant-velocity test: torque minus gravity against speed, points and the
eq. 5 line), Fig. 3 (RLS convergence of J_4z, B_4, f_c4 — or any parameters — under the mixed and the simultaneous
method), measured vs predicted torque on the validation data, and the tables behind them.
"""
from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def png_base64(fig) -> str:
    """The figure as a base64 PNG for an inline <img> (the figure is closed)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    pyplot().close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def fig2(ident, axes=None):
    """The paper's Fig. 2 for every axis with a constant-velocity test. Returns a matplotlib Figure or None."""
    plt = pyplot()
    vt = ident.velocity
    if vt is None or not vt.axes_:
        return None
    ms = sorted(vt.axes_) if axes is None else axes
    cols = min(3, len(ms))
    rows = int(np.ceil(len(ms) / cols))
    fig, axs = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.3 * rows), squeeze=False)
    for a, m in zip(axs.ravel(), ms):
        ax = vt.axes_[m]
        p = ax.points
        a.errorbar(p[:, 0], p[:, 1], yerr=p[:, 2], fmt="o", ms=4, label="steady segments")
        x = np.linspace(p[:, 0].min(), p[:, 0].max(), 200)
        x = x[x != 0]
        for sgn in (1, -1):
            xs = x[np.sign(x) == sgn]
            a.plot(xs, ax.viscous * xs + ax.coulomb * sgn, "r-", lw=1)
        a.axhline(0, color="0.7", lw=0.5)
        a.axvline(0, color="0.7", lw=0.5)
        a.set_title(f"axis {m + 1}: B={ax.viscous:.3g}±{ax.viscous_std:.1g}, f_c={ax.coulomb:.3g}±{ax.coulomb_std:.1g}",
                    fontsize=8)
        a.set_xlabel("motor speed θ̇_m (rad/s)")
        a.set_ylabel("τ_m − K^T G(θ) (N m)")
    for a in axs.ravel()[len(ms):]:
        a.axis("off")
    fig.suptitle("Fig. 2 — constant angular velocity test (eq. 5): slope B, intercept f_c")
    fig.tight_layout()
    return fig


def fig3(ident, params=None):
    """The paper's Fig. 3: RLS convergence of the chosen parameters under both methods."""
    plt = pyplot()
    params = list(params or ident.options.fig3)
    fig, axs = plt.subplots(len(params), 1, figsize=(7, 2.3 * len(params)), squeeze=False)
    for a, name in zip(axs[:, 0], params):
        i = ident.param_index(name)
        for mname, style in (("mixed", "b-"), ("simultaneous", "r--")):
            if mname not in ident.methods:
                continue
            mr = ident.methods[mname]
            a.plot(mr.history_iter, mr.history[:, i], style, label=f"{mname}: {mr.beta[i]:.4g}")
        # y-range from the converged part (the first checkpoints of a weak-prior RLS swing wildly)
        tail = np.concatenate([ident.methods[m].history[len(ident.methods[m].history) // 5:, i]
                               for m in ident.methods])
        lo, hi = np.min(tail), np.max(tail)
        pad = 0.5 * max(hi - lo, 0.2 * max(abs(hi), abs(lo)), 1e-12)
        a.set_ylim(lo - pad, hi + pad)
        a.set_ylabel(name, fontsize=9)
        a.set_title(ident.bp.names[i][:110], fontsize=7)
        a.legend(fontsize=7)
    axs[-1, 0].set_xlabel("RLS iteration (samples)")
    fig.suptitle("Fig. 3 — convergence under the mixed and the simultaneous method")
    fig.tight_layout()
    return fig


def _validation_time(ident) -> np.ndarray | None:
    """Time (s) of every validation sample, from the signals it was taken from (None if unknown)."""
    where = ident.val_data.get("where") if ident.val_data else None
    if not where:
        return None
    t = np.concatenate([sig.t[idx] for sig, idx in where])
    return t if len(t) == len(ident.validation["measured"]) else None


def fig_validation(ident):
    """Measured vs predicted (exported model and textbook OLS) torque per axis on the held-out data, each with its
    residual panel, against time in seconds."""
    plt = pyplot()
    v = ident.validation
    Y = v["measured"]
    P = v[v.get("exported", ident.chosen)]["pred"]
    B = v["baseline"]["pred"] if "baseline" in v else None
    n = Y.shape[1]
    t = _validation_time(ident)
    xlab = "time in its log (s); held-out stretches joined" if t is not None else "validation sample"
    x = np.arange(len(Y))
    fig, axs = plt.subplots(2 * n, 1, figsize=(9, 2.2 * n), sharex=True, squeeze=False,
                            gridspec_kw={"height_ratios": [2, 1] * n})
    for k in range(n):
        a, r = axs[2 * k, 0], axs[2 * k + 1, 0]
        a.plot(x, Y[:, k], "k-", lw=0.8, label="measured (filtered)")
        a.plot(x, P[:, k], "r-", lw=0.8, label="js2 exported model")
        if B is not None:
            a.plot(x, B[:, k], "b:", lw=0.8, label="textbook OLS")
        a.set_ylabel(f"τ {k + 1} (N m)", fontsize=8)
        a.text(0.01, 0.85, f"RMS {v['rms'][k]:.3g} N m, NRMS {100 * v['nrms'][k]:.2f} %", transform=a.transAxes,
               fontsize=7)
        r.plot(x, P[:, k] - Y[:, k], "r-", lw=0.6)
        if B is not None:
            r.plot(x, B[:, k] - Y[:, k], "b:", lw=0.6)
        r.axhline(0, color="0.6", lw=0.5)
        r.set_ylabel("residual", fontsize=7)
    axs[0, 0].legend(fontsize=7, loc="upper right")
    if t is not None:
        ticks = np.linspace(0, len(Y) - 1, 7).astype(int)
        axs[-1, 0].set_xticks(ticks)
        axs[-1, 0].set_xticklabels([f"{t[i]:.1f}" for i in ticks])
    axs[-1, 0].set_xlabel(xlab)
    fig.suptitle("Validation: torque predicted vs measured on data not used for fitting (residual below each axis)")
    fig.tight_layout()
    return fig


POOR_REL_STD = 0.3
NEXT_STEPS = """<h2>What to do next, and which file holds what</h2><ul>
<li><b>model.yaml</b>: friction, motor inertias, offsets, base parameters with std, validation beside the textbook
baseline, every automatic choice (notes). <b>robot_identified.urdf</b>: the exported links for a simulator or a
controller. <b>verdict.json</b>: the checks and, for each failure, the reason.</li>
<li>Verdict FAIL on units or masses: check the torque unit and <code>torque_side</code> in drives.yaml, then re-import.</li>
<li>Poorly identified base parameters or a high condition number: record a richer excitation (more axes moving
together, larger speed range) and identify again.</li>
<li>Large residual on one axis: run <code>js2-diagnose model.yaml LOG</code> to name the physics the model leaves
out.</li></ul>"""


def _unit(lead: str, arm) -> str:
    """SI unit of a base parameter from its leading standard parameter (motor or joint side as the log)."""
    kind = lead.split("_")[0]
    return {"m": "kg", "mx": "kg m", "my": "kg m", "mz": "kg m", "Ja": "kg m²", "B": "N m s/rad", "fc": "N m",
            "off": "N m", "Bs": "N m (s/rad)^0.5"}.get(kind, "kg m²")


def html_table(headers, rows) -> str:
    """An HTML table, every cell escaped."""
    h = "".join(f"<th>{html.escape(str(x))}</th>" for x in headers)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _f(x, p=4):
    try:
        return "—" if x is None or not np.isfinite(x) else f"{x:.{p}g}"
    except TypeError:
        return str(x)


def write_report(ident, outdir: Path, verdict: dict | None = None) -> Path:
    figs = []
    f2 = fig2(ident)
    if f2 is not None:
        figs.append(("Fig. 2 — constant-velocity test per axis", png_base64(f2)))
    figs.append(("Fig. 3 — RLS convergence, mixed vs simultaneous", png_base64(fig3(ident))))
    figs.append(("Validation", png_base64(fig_validation(ident))))
    arm = ident.arm
    ja, ja_sd, alone = ident.motor_inertia()
    sd = ident.static_per_direction or {}
    fr_rows = [[j, _f(ident.friction_static[k]) + (f" (+{_f(sd[k]['+'], 3)} / −{_f(sd[k]['-'], 3)})" if k in sd else ""),
                _f(ident.friction_static_std[k], 2), _f(ident.friction_coulomb[k]),
                _f(ident.friction_coulomb_std[k], 2), _f(ident.friction_viscous[k]), _f(ident.friction_viscous_std[k], 2),
                _f(ja[k]), "yes" if alone[k] else "regrouped (value from the consistent fit)"]
               for k, j in enumerate(arm.joints)]
    bp_rows = []
    for i in range(ident.bp.n):
        row = [ident.bp.names[i], _unit(ident.bp.lead(i), arm)]
        for m in ("mixed", "simultaneous"):
            if m in ident.methods:
                mr = ident.methods[m]
                rel = abs(mr.std[i] / mr.beta[i]) if mr.beta[i] != 0 else np.inf
                flag = " (poorly identified)" if rel > POOR_REL_STD else ""
                row += [_f(mr.beta[i]), _f(mr.std[i], 2), f"{100 * rel:.3g} %{flag}" if np.isfinite(rel) else "—"]
        bp_rows.append(row)
    bp_head = ["base parameter", "unit"] + sum([[f"{m}", "std", "relative std"] for m in ("mixed", "simultaneous")
                                                if m in ident.methods], [])
    link_rows = []
    if ident.physical is not None:
        nom = np.asarray(arm.nominal_inertial, float).reshape(arm.n, 10)
        for lk, p, q in zip(arm.links, ident.physical.links_, nom):
            com = p[1:4] / p[0]
            com_n = q[1:4] / q[0] if q[0] > 0 else np.full(3, np.nan)
            link_rows.append([lk, _f(p[0], 4), _f(q[0], 4), ", ".join(_f(c, 3) for c in com),
                              ", ".join(_f(c, 3) for c in com_n), ", ".join(_f(c, 3) for c in p[[4, 6, 9]]),
                              ", ".join(_f(c, 3) for c in q[[4, 6, 9]])])
    v = ident.validation
    val_rows = []
    for k, j in enumerate(arm.joints):
        row = [j]
        for key in ("mixed", "simultaneous", "mixed_wls", "physical", "baseline"):
            if key in v:
                row.append(_f(v[key]["rms"][k], 3))
        row.append(f"{100 * v['nrms'][k]:.2f} %")
        row.append(f"{100 * v['rel'][k]:.2f} %")
        if "baseline" in v:
            row.append(f"{100 * v['baseline']['rel'][k]:.2f} %")
        val_rows.append(row)
    keys = [k for k in ("mixed", "simultaneous", "mixed_wls", "physical") if k in v]
    val_head = ["axis"] + [f"RMS {k} (N m)" for k in keys] + (["RMS textbook OLS (N m)"] if "baseline" in v else []) \
        + [f"NRMS (exported: {v['exported']})", "relative error, exported"] \
        + (["relative error, textbook OLS"] if "baseline" in v else [])
    if "baseline" in v:
        val_rows.append(["overall"] + [""] * (len(keys) + 2) + [f"{100 * v['rel_overall']:.2f} %",
                                                               f"{100 * v['baseline']['rel_overall']:.2f} %"])
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>js2 identification report</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;font-size:12px}"
        "td,th{border:1px solid #ccc;padding:2px 6px}h2{margin-top:28px}.pass{color:green}.fail{color:red}"
        "img{max-width:100%;height:auto}</style>",
        "</head><body>",
        f"<h1>js2 identification — {html.escape(ident.logs[0].robot)}</h1>",
        f"<p>Method: <b>{ident.chosen}</b>. Condition number of the base regressor (columns normalised): "
        f"{ident.condition_number:.4g} (unscaled {ident.condition_number_raw:.3g}); {ident.bp.n} base parameters; "
        f"{ident.n_fit_samples} fitting samples, RLS over {ident.model.rls.n_iter_} iterations.</p>",
    ]
    if verdict is not None:
        cls = "pass" if verdict["pass"] else "fail"
        parts.append(f"<p>Verdict: <b class='{cls}'>{'PASS' if verdict['pass'] else 'FAIL'}</b></p>")
        parts.append("".join(f"<p class='fail'>{html.escape(r)}</p>" for r in verdict.get("reasons", [])))
        parts.append(html_table(["check", "value", "threshold", "pass"],
                            [[c["check"], _f(c["value"]) if not isinstance(c["value"], bool) else c["value"],
                              c.get("threshold", ""), c["pass"]] for c in verdict["checks"]]))
    parts.append("<h2>Inputs</h2>" + html_table(["log", "sha256", "source", "truncated", "trials"],
                                            [[i["path"], i["sha256"][:16] + "…", i["source"], i["truncated"],
                                              ", ".join(i["trials"])] for i in ident.inputs]))
    if ident.notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in ident.notes) + "</ul>")
    parts.append("<h2>Drive parameters (motor side)</h2>" + html_table(
        ["axis", "f_s (N m) (per direction)", "std", "f_c (N m)", "std", "B (N m s/rad)", "std", "J_a (kg m²)", "J_a separately"],
        fr_rows))
    parts.append("<h2>Validation (held-out data; the exported model beside the textbook OLS fit)</h2>"
                 + html_table(val_head, val_rows))
    if link_rows:
        parts.append("<h2>Identified links beside the nominal URDF</h2>"
                     "<p>Mass (kg), centre of mass (m, link frame) and Ixx, Iyy, Izz about the joint frame origin "
                     "(kg m²). Where the data cannot separate masses, the fit keeps the URDF's split (prior weight "
                     f"{_f(ident.physical.prior_weight, 3)}).</p>"
                     + html_table(["link", "mass", "mass URDF", "COM", "COM URDF", "Ixx, Iyy, Izz", "URDF"],
                                  link_rows))
    for title, b64 in figs:
        parts.append(f"<h2>{html.escape(title)}</h2><img src='data:image/png;base64,{b64}' "
                     f"alt='{html.escape(title, quote=True)}'/>")
    parts.append(f"<h2>Base parameters</h2><p>Flagged: relative std above {100 * POOR_REL_STD:.0f} %.</p>"
                 + html_table(bp_head, bp_rows))
    parts.append(NEXT_STEPS)
    parts.append("</body></html>")
    p = outdir / "report.html"
    p.write_text("\n".join(parts))
    return p
