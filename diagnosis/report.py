"""Diagnosis outputs in OUTDIR: ``diagnosis.json``, ``model_diagnosed.yaml`` (model.yaml + ``unmodelled:``),
``effects.yaml`` (the found effects in ``hil_sim`` format) and ``report.html`` (figures inline)."""
from __future__ import annotations

import html
import json
import shutil
from pathlib import Path

import numpy as np
import yaml

from identification.report import html_table, png_base64, pyplot
from js2spec.effects import parse_effects, units_comment

from .residual import motor_rows
from .run import DiagnosisResult

FRICTION_KINDS = {"stribeck", "asymmetric_friction", "thermal_drift", "load_dependent_friction"}


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def fig_rms(res: DiagnosisResult):
    plt = pyplot()
    motors = res.location["motors"]          # each motor in the band its findings were proven in
    n = len(motors)
    fig, ax = plt.subplots(figsize=(7, 3))
    x = np.arange(n)
    ax.bar(x - 0.2, np.array([m["holdout_rms_before"] for m in motors], float), 0.4, label="model")
    ax.bar(x + 0.2, np.array([m["holdout_rms_after"] for m in motors], float), 0.4, label="model + found terms")
    ax.set_xticks(x, [f"motor {i + 1}" + ("\n(unfiltered)" if m["band"] == "wide" else "")
                      for i, m in enumerate(motors)])
    ax.set_ylabel("report-rows residual RMS (N m)")
    ax.set_title("Residual on the report rows (never seen by the search)")
    ax.legend(fontsize=8)
    return fig


def fig_finding(res: DiagnosisResult, k: int):
    """Held-out torque of the finding's main motor (measured, model, model + terms) and the residual against the
    finding's natural axis, before and after."""
    plt = pyplot()
    rd = res.rd
    sc = res.accepted[k]
    f = sc.fitted
    i = int(f.effect["joints"][0]) if f.kind != "payload_change" else int(np.argmax(sc.rms_before - sc.rms_after))
    rows = np.flatnonzero(motor_rows(rd.holdout_rows, i) & rd.mask[:, i])
    corr = res.search.predict(rd, sc.band)
    meas = rd.tau_meas if sc.band == "low" else rd.tau_meas_raw
    pred = rd.tau_pred if sc.band == "low" else rd.tau_pred_raw
    fig, axs = plt.subplots(1, 2, figsize=(12, 3.4))
    if len(rows):
        # the whole report span; samples left out (at rest, lost, other trials) are gaps in the lines, not joins
        span = np.arange(rows[0], rows[-1] + 1)
        shown = np.zeros(len(rd.t), bool)
        shown[rows] = True

        def gaps(x):
            return np.where(shown[span], x[span], np.nan)

        t = rd.t[span]
        axs[0].plot(t, gaps(meas[:, i]), "k-", lw=0.6, label="measured")
        axs[0].plot(t, gaps(pred[:, i]), "C0-", lw=1, label="model")
        axs[0].plot(t, gaps(pred[:, i] + corr[:, i]), "C3-", lw=1, label="model + found terms")
        axs[0].set_xlabel("t (s), report rows (gaps: samples left out)")
        axs[0].set_ylabel(f"motor {i + 1} torque (N m)")
        axs[0].legend(fontsize=7)
    r0 = (meas - pred)[rows, i]
    r1 = (meas - pred - corr)[rows, i]
    if f.kind == "cogging":
        periods = int(f.effect["periods_per_rev"])      # the hyper-parameter alone, or (periods, pass band)
        x = np.mod(rd.q_motor[rows, i] * periods, 2 * np.pi)
        xl = f"motor angle x {periods} mod 2 pi (rad)"
    elif f.kind == "thermal_drift":
        x, xl = rd.t[rows], "time (s)"
    elif f.kind in FRICTION_KINDS:
        x, xl = rd.dq_motor[rows, i], f"motor {i + 1} speed (rad/s)"
    else:                    # payload, elasticity, backlash: against the same motor's model torque
        x, xl = rd.tau_rigid_motor[rows, i], f"motor {i + 1} model torque (N m)"
    axs[1].plot(x, r0, ".", ms=1.5, alpha=0.5, label="residual, model")
    axs[1].plot(x, r1, ".", ms=1.5, alpha=0.5, label="residual, model + found terms")
    axs[1].set_xlabel(xl)
    axs[1].set_ylabel(f"motor {i + 1} residual (N m)")
    axs[1].legend(fontsize=7, markerscale=5)
    fig.suptitle(f"{f.kind} on {rd.joints[f.effect['joints'][0]]}: {f.summary}", fontsize=9)
    return fig


def _g(x, p=3):
    if isinstance(x, (list, tuple)):
        return ", ".join(_g(v, p) for v in x)
    if isinstance(x, str):                  # a named hyper-parameter value (thermal_drift's heat source)
        return x
    return "–" if x is None or (isinstance(x, float) and not np.isfinite(x)) else f"{x:.{p}g}"


def unconfirmed(d: dict) -> list[dict]:
    """The named findings whose own report gain is negative: on the report rows (never seen by the search, which
    chose them on the select rows) their motors' residual grows. Said, not undone: the report rows score, they do
    not choose. On clean real recordings diagnosed with another recording's model (scripts/bench_diagnose_real_clean.py)
    two of the false names read so (-27 % and -3.6 %)."""
    return [f for f in d["findings"] if f.get("holdout_gain") is not None and f["holdout_gain"] < 0]


def gain_scope(d: dict) -> str:
    """What the headline gain scores: the found terms, and the refits reported unexplained when there are (they are
    part of the corrected model it is computed on)."""
    return "the found terms and the refits reported unexplained" if d["findings"] and d["unexplained"] else \
        "the found terms"


def headline(d: dict) -> str:
    """One sentence: is there a mismatch, what is it, and how much of the report-rows residual the findings remove
    (with the refits reported unexplained, when there are: they are part of the corrected model the gain scores);
    then the findings the report rows do not confirm, if any."""
    if d["findings"]:
        names = "; ".join(f"{f['kind']} on {f['joint']}" for f in d["findings"])
        text = (f"Mismatch found: the model leaves out {names}. Together {gain_scope(d)} remove "
                f"{d['holdout_gain']:.0%} of the residual on the report rows, which the search never saw.")
        weak = unconfirmed(d)
        if weak:
            text += (" Not confirmed there: " + "; ".join(
                f"{f['kind']} on {f['joint']} makes its motors' report residual {-f['holdout_gain']:.0%} worse"
                for f in weak) + " (a lead to check on another recording, not a finding to act on).")
        return text
    if d["unexplained"]:
        return ("Mismatch, but no named physics: the residual on "
                + ", ".join(f"{u['joint']} ({u['regime'] or 'every regime'}, mostly {u['frequency_band']}; what "
                            f"takes it: {u.get('reference') or 'a refit of the model'})" for u in d["unexplained"])
                + " has structure that no named effect explains better than these readings (unexplained).")
    return "No mismatch that any candidate term explains on held-out data: the model is complete as far as this " \
           "recording can tell."


def next_step(d: dict) -> str:
    if d["findings"] and len(unconfirmed(d)) == len(d["findings"]):
        return ("Record another session of this arm (or one with a 'validation' trial) and diagnose it with the same "
                "model: what the report rows did not confirm here should be found again before it goes into "
                "model_diagnosed.yaml's `unmodelled:` or effects.yaml.")
    if d["findings"]:
        return ("model_diagnosed.yaml is the model plus `unmodelled:` (the found effects with their parameters) for "
                "your controller or simulator; effects.yaml simulates them with hil_sim (sim_truth.yaml `effects:`). "
                "Confirm on a recording this diagnosis did not see: the same effects should be found again.")
    if d["unexplained"]:
        return ("Re-identify the friction of the joints named unexplained (js2-identify with a velocity trial), or "
                "record a longer session with a 'validation' trial, and diagnose again.")
    return "Nothing to change."


def effects_yaml(res: DiagnosisResult, path: Path) -> str:
    """The found effects in the simulator's config form, validated against the one effect schema
    (:mod:`js2spec.effects`, which ``hil_sim`` parses with), parameters in the schema's order and units."""
    effects = parse_effects(res.sim_effects(), res.rd.n, source=path, joints=res.rd.joints)
    head = ("# effects the diagnosis found; simulate them with hil_sim (sim_truth.yaml `effects:`, Plant(effects=...)\n"
            "# or js2-sim --replay RECORDING --model MODEL --effects THIS_FILE). Units (js2spec.effects):\n")
    return head + units_comment() + "\n" + yaml.safe_dump(
        {"effects": _jsonable([e.as_config() for e in effects])}, sort_keys=False)


def fig_replay(res: DiagnosisResult, arrays: dict, motors: list[int]):
    """Recording vs simulation over the report rows (gaps shown as gaps), one panel per motor: measured torque, the
    simulator with the model, the simulator with the model plus the found effects."""
    plt = pyplot()
    rd = res.rd
    fig, axs = plt.subplots(len(motors), 1, figsize=(12, 2.4 * len(motors)), squeeze=False)
    for ax, i in zip(axs[:, 0], motors):
        r = arrays["rows"][:, i]
        t = rd.t
        for y, style, lab in ((rd.tau_meas[:, i], "k-", "recording"), (arrays["tau_model"][:, i], "C0-",
                                                                      "simulator: model"),
                              (arrays["tau_effects"][:, i], "C3-", "simulator: model + found effects")):
            ax.plot(t, np.where(r, y, np.nan), style, lw=0.8, label=lab)
        ax.set_ylabel(f"motor {i + 1} torque (N m)")
    axs[0, 0].legend(fontsize=7, loc="upper right")
    axs[-1, 0].set_xlabel("t (s), report rows (moving samples; gaps are rows not compared)")
    fig.suptitle("Recording vs simulation (hil_sim replay of the recorded motion)", fontsize=9)
    fig.tight_layout()
    return fig


def replay_html(res: DiagnosisResult, rep: dict, arrays: dict) -> str:
    """The report's replay section: a table per motor and the torque-over-time figure of the motors the effects
    change most."""
    fw = rep["forward"]
    rows = [[f"motor {i + 1}", j, _g(b), _g(a), f"{x:.0%}" if x is not None else "–", _g(p0), _g(p1), _g(t0), _g(t1)]
            for i, (j, b, a, x, p0, p1, t0, t1) in enumerate(zip(
                rep["joints"], rep["rms_model"], rep["rms_model_effects"], rep["drop"],
                fw["model"]["position_rms"], fw["model_effects"]["position_rms"],
                fw["model"]["tracking_torque_rms"], fw["model_effects"]["tracking_torque_rms"]))]
    change = [(b or 0) - (a or 0) for b, a in zip(rep["rms_model"], rep["rms_model_effects"])]
    motors = sorted(np.argsort(change)[::-1][:3].tolist())
    eff = ", ".join(f"{e['kind']} on {res.rd.joints[e['joints'][0]]}" for e in rep["effects"]) or "none found"
    gain = f"{rep['gain']:.1%}" if rep["gain"] is not None else "–"
    skipped = (f" Not simulated (no hil_sim implementation): {', '.join(rep['not_simulated'])}."
               if rep["not_simulated"] else "")
    return (f"<h2>Simulation against the recording</h2><p>The recorded motion replayed through the simulator "
            f"(<code>hil_sim</code>, {html.escape(rep['mode'])}) with the identified model, then with the model plus "
            f"the found effects ({html.escape(eff)}).{html.escape(skipped)} RMS of recording minus simulation on the "
            f"{html.escape(rep['rows'])}; together the effects remove {gain} of the gap "
            f"({html.escape(rep['gain_definition'])}).</p>"
            + html_table(["motor", "joint", "torque gap (inverse), model (N m)", "model + effects (N m)", "drop",
                          "joint angle gap (forward), model (rad)", "model + effects (rad)",
                          "tracking torque, model (N m)", "model + effects (N m)"], rows)
            + f"<p>Forward replay: {html.escape(fw['what'])}; followed {fw['model']['followed']:.0%} (model), "
              f"{fw['model_effects']['followed']:.0%} (model + effects).</p>"
            + f"<img src='data:image/png;base64,{png_base64(fig_replay(res, arrays, motors))}'>")


def write_outputs(res: DiagnosisResult, outdir: str | Path, replay: bool = False) -> dict[str, Path]:
    """``replay``: also replay the recording through hil_sim (``diagnosis.replay``): ``diagnosis.json`` ``replay``
    and a report section."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    d = _jsonable(res.to_dict())
    d["headline"] = headline(d)
    d["unconfirmed"] = [{"kind": f["kind"], "joint": f["joint"], "holdout_gain": f["holdout_gain"]}
                        for f in unconfirmed(d)]
    d["next_step"] = next_step(d)
    rep_html = ""
    if replay:
        from .replay import replay_section

        rep, arrays = replay_section(res)
        d["replay"] = _jsonable(rep)
        rep_html = replay_html(res, d["replay"], arrays)
    paths = {"json": out / "diagnosis.json", "model": out / "model_diagnosed.yaml", "effects": out / "effects.yaml",
             "report": out / "report.html"}
    paths["json"].write_text(json.dumps(d, indent=1))
    paths["model"].write_text(yaml.safe_dump(_jsonable(res.diagnosed_model()), sort_keys=False))
    if res.model.urdf_path is not None and res.model.urdf_path.is_file():
        dst = out / res.model.urdf_path.name
        if dst.resolve() != res.model.urdf_path.resolve():
            shutil.copyfile(res.model.urdf_path, dst)
    paths["effects"].write_text(effects_yaml(res, paths["effects"]))
    figs = [("Held-out residual per motor", png_base64(fig_rms(res)))]
    for k in range(len(res.accepted)):
        figs.append((f"Finding {k + 1}", png_base64(fig_finding(res, k))))
    rows = [[f["kind"], f["joint"], str(f["hyper"]), f"{f['holdout_gain']:.1%}", f"{f['fit_gain']:.1%}",
             "; ".join(f"{_g(c)} ± {_g(e, 2)}" for c, e in zip(f["coefficients"], f["coefficients_std"])),
             f["summary"]] for f in d["findings"]]
    cand = [[c["kind"], c["joint"], _g(c["hyper"]), f"{c['select_gain_all']:.1%}", f"{c['select_gain']:.1%}",
             f"{c['fit_gain']:.1%}", "yes" if c["plausible"] and not c["why_not"] else f"no: {c['why_not']}"]
            for c in d["candidates_step1"]]
    loc_rows = [[f"motor {m['motor'] + 1}", m["joint"],
                 "unfiltered" if m.get("band") == "wide" else "torque band",
                 _g(m["holdout_rms_before"]), _g(m["holdout_rms_after"]),
                 f"{m['holdout_drop']:.0%}" if m["holdout_drop"] is not None else "–", m["worst_regime"] or "–",
                 f"{m['dominant_band']} ({m['dominant_band_share']:.0%})" if m.get("dominant_band") else "–",
                 "yes" if m["flagged"] else ""] for m in d["location"]["motors"]]
    body = [f"<h1>js2 diagnosis</h1><p><b>Model</b> {html.escape(d['model'])}<br><b>Recording</b> "
            f"{html.escape(', '.join(d['recordings']))}<br><b>Split</b> {html.escape(d['split'])}</p>",
            f"<h2>Answer</h2><p style='font-size:1.15em'>{html.escape(headline(d))}</p>",
            f"<h2>Verdict</h2><p>{html.escape(d['verdict'])}</p>",
            f"<h2>Where</h2><p>{html.escape(d['location']['text'])}</p>",
            html_table(["motor", "joint", "scored in", "held-out RMS before (N m)", "after", "drop", "largest in",
                        "left after the findings: most power in", "mismatch"], loc_rows),
            "<h2>What was found</h2>" + (html_table(["kind", "joint", "hyper-parameter", "report gain", "fit gain",
                                                 "coefficients ± std (fit)", "what it means"], rows)
                                     if rows else "<p>nothing</p>"),
            "<h2>Candidates tried (first step, best first)</h2>",
            html_table(["kind", "joint", "hyper", "select gain (all motors)", "select gain (its motors)",
                    "fit gain", "passes"], cand)]
    for title, png in figs:
        body.append(f"<h2>{html.escape(title)}</h2><img src='data:image/png;base64,{png}'>")
    if rep_html:
        body.append(rep_html)
    body.append("<h2>Next step</h2><p>" + html.escape(next_step(d)) + "</p><p><small>Gains: "
                + html.escape(d["holdout_gain_definition"]) + ". Torques in N m, motor side; speeds in rad/s; "
                "parameters in the units of hil_sim's effects (frames named in each finding).</small></p>")
    if d["notes"]:
        body.append("<h2>Notes</h2><ul>" + "".join(f"<li>{html.escape(str(n))}</li>" for n in d["notes"]) + "</ul>")
    style = ("<style>body{font-family:sans-serif;max-width:1200px;margin:auto}table{border-collapse:collapse}"
             "td,th{border:1px solid #ccc;padding:3px 6px;font-size:13px}</style>")
    paths["report"].write_text(f"<!doctype html><html><head><meta charset='utf-8'><title>js2 diagnosis</title>"
                               f"{style}</head><body>{''.join(body)}</body></html>")
    return paths
