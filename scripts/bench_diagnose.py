#!/usr/bin/env python3
"""Benchmark js2-diagnose on randomised simulator cases: confusion matrix and parameter errors.

1. the simulated Js-2 runs the identification trials with no hidden effect; js2-identify makes the model (once);
2. case k (seed k, fixed): a random draw of 0, 1 or 2 effects (kind, joint or link, magnitude), a random
   excitation + validation trajectory (the trials' Fourier seeds, periods, harmonics, centres and amplitudes, so no
   two cases share a trajectory), a random sample rate (250, 500 or 1000 Hz: the simulated drives' cycle) and a
   random host controller (the trajectory controller's gains scaled by 0.6-1.6); the simulator records it with
   those effects, the model (identified at 500 Hz) knows none of them;
3. js2-diagnose with its defaults (no flags) names what it finds; a true effect counts as found when the same kind
   is named on the same joint (payload: the same link; coupling: the same driven joint and the same ``from_joint``).

Cases 0-47 draw from the first eight kinds (their recordings are kept); cases from 48 on also conceal ``coupling``
(``NEW_KINDS``): e.g. ``--first 48 --cases 16``; cases from 96 on put backlash, joint elasticity or cogging first
(``HARD_FROM``), a cogging half the time with 12-24 periods per revolution.

Prints the confusion matrix (rows: concealed kind, or `none` for a clean case; columns: what was named on that
joint, `nothing` when nothing was) plus the false names (named where nothing of that kind was concealed), the rates
and the parameter errors; writes OUT/bench.json.

    .venv/bin/python scripts/bench_diagnose.py [--cases 48] [--first 0] [--out runs/bench_diagnose]
        [--keep-recordings] [--record-only] [--rediagnose]
    .venv/bin/python scripts/bench_diagnose.py --from-json docs/bench/diagnose-bench-all-2026-11-24.json
    .venv/bin/python scripts/bench_diagnose.py --first 0 --cases 160 --log-hz 100 --out runs/log100
        --recordings-from runs/bench_diagnose --visibility-from runs/bench_diagnose

``--log-hz HZ`` diagnoses each case's recording read every k-th SYNC cycle (k = round(drawn rate / HZ); the drives'
loop runs at the drawn rate, as a fast loop logged slowly: ``js2spec.resample.decimate_log``); with
``--recordings-from`` the drawn-rate recordings of an earlier ``--keep-recordings`` run are used (linked, not
simulated again), and ``--visibility-from`` takes their visibilities (stop 33's rows:
docs/bench/diagnose-bench-log100-2026-11-27-stop33.json).

Simulating a case takes about a minute on one free core; --cases sets how many are run (results are cached per
case in OUT/case_NNN.json, so a longer run resumes). With --keep-recordings the recordings stay in OUT/runs/, and
--rediagnose runs only the diagnosis again on them (after a change to the diagnosis); --record-only simulates the
cases without diagnosing them.
"""
from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from pathlib import Path

import numpy as np

KINDS = ("stribeck", "cogging", "payload_change", "thermal_drift", "load_dependent_friction", "asymmetric_friction",
         "joint_elasticity", "backlash")          # the kinds cases 0-47 conceal (their draw order fixes those cases)
#: kinds added after the first 48 cases were recorded: drawn only for cases from NEW_KINDS_FROM on, so that cases
#: 0-47 (and their kept recordings) stay what they were
NEW_KINDS = ("coupling",)
NEW_KINDS_FROM = 48
ALL_KINDS = KINDS + NEW_KINDS
NAMED = ALL_KINDS + ("torque_offset",)           # what the diagnosis can name (columns of the confusion matrix)


#: cases from here on draw a thermal drift by the friction change it makes (either heat source) rather than by its
#: heating coefficient, and cap the host controller's gains at 250 Hz (cases 0-55 are unchanged): the heating drawn
#: for cases 0-55 (3-8 K/A^2 on every motor) changed the wrist motors' friction by under 2 %, below what any term
#: can show, and 250 Hz draws with gains above 1 made clean recordings chatter at 22 Hz
SIZED_FROM = 56
#: mean I^2 (A^2) and friction power |f w| (W) per motor over the benchmark's trajectories: medians over 12 kept
#: recordings (cases 0, 4, ..., 44; the model's friction along the recorded speed), to turn a drawn friction change
#: into a heating coefficient
#: cases from here on put the kinds the diagnosis finds hardest first, in turn (backlash, joint elasticity, cogging),
#: and draw a cogging half the time with a fine ripple (12, 18 or 24 periods per motor revolution, as the independent
#: simulator's): cases 56-95 drew mostly thermal drifts and couplings, so the fresh cases 72-95 did not test these
#: kinds (cases 0-95 are unchanged)
HARD_FROM = 96
HARD_KINDS = ("backlash", "joint_elasticity", "cogging")
#: cases from here on draw a play's contact stiffness (log-uniform over CONTACT_STIFFNESS, N*m/rad joint side)
#: instead of the one 3000 N*m/rad every earlier play has (cases 0-579 are unchanged). The springs are drawn over
#: 800-3000 N*m/rad: with one contact stiffness inside that range, a rule telling a play from a spring by how the
#: link follows the gear would be a rule on that one number (stop 37: the 500 Hz shoulder plays miss 1.16-1.20 of
#: the link's torque in their limit cycle, the springs 1.02-1.17, and no bound was drawn from it)
CONTACT_FROM = 580
CONTACT_STIFFNESS = (2000.0, 20000.0)
MEAN_CURRENT_SQUARED = (0.354, 5.25, 1.55, 0.153, 0.120, 0.093)
MEAN_FRICTION_POWER = (2.21, 1.19, 0.600, 0.354, 0.399, 0.319)


def draw_effect(rng: np.random.Generator, kind: str, n: int, sized: bool = False, fine: bool = False,
                contact: bool = False) -> dict:
    """One effect of ``kind`` at a random joint with a random magnitude (ranges: docs/diagnosis.md). ``sized``
    (cases from SIZED_FROM on): a thermal drift raises its motor's friction by 20-60 % at steady state (the
    independent simulator's raised B by 50-90 %), heated by I^2 or by the friction power. ``contact`` (cases from
    CONTACT_FROM on): a play's contact stiffness is drawn (CONTACT_STIFFNESS), not 3000 N*m/rad."""
    if kind == "thermal_drift" and sized:
        j = int(rng.integers(0, n))
        change, alpha = float(rng.uniform(0.2, 0.6)), float(rng.uniform(0.01, 0.03))
        e = {"kind": kind, "joints": [j], "time_constant": float(rng.uniform(10.0, 40.0)), "friction_per_kelvin": alpha}
        if rng.uniform() < 0.5:
            e["heating"] = change / (alpha * MEAN_CURRENT_SQUARED[j])
        else:
            e["heating"] = 0.0
            e["friction_power_heating"] = change / (alpha * MEAN_FRICTION_POWER[j])
        return e
    if kind == "stribeck":
        return {"kind": kind, "joints": [int(rng.integers(0, n))], "velocity": float(rng.uniform(2.0, 8.0)),
                "shape": float(rng.choice([1.0, 2.0]))}
    if kind == "cogging":
        e = {"kind": kind, "joints": [int(rng.integers(0, n))], "amplitude": float(rng.uniform(0.003, 0.008)),
             "periods_per_rev": int(rng.choice([1, 2, 3, 4])), "phase": float(rng.uniform(-np.pi, np.pi))}
        if fine and rng.uniform() < 0.5:          # ``fine`` (cases from HARD_FROM on): 12, 18 or 24 per revolution
            e["periods_per_rev"] = int(rng.choice([12, 18, 24]))
        return e
    if kind == "payload_change":
        return {"kind": kind, "joints": [int(rng.integers(3, n))], "mass": float(rng.uniform(0.15, 0.8)),
                "com": [float(x) for x in rng.uniform(-0.05, 0.05, 3)]}
    if kind == "thermal_drift":
        return {"kind": kind, "joints": [int(rng.integers(0, n))], "heating": float(rng.uniform(3.0, 8.0)),
                "time_constant": float(rng.uniform(10.0, 40.0)), "friction_per_kelvin": float(rng.uniform(0.008, 0.02))}
    if kind == "load_dependent_friction":
        return {"kind": kind, "joints": [int(rng.integers(0, 3))], "coefficient": float(rng.uniform(0.08, 0.25))}
    if kind == "asymmetric_friction":
        return {"kind": kind, "joints": [int(rng.integers(0, n))],
                "negative_scale": float(rng.choice([rng.uniform(1.3, 1.8), rng.uniform(0.55, 0.75)]))}
    if kind == "joint_elasticity":
        return {"kind": kind, "joints": [int(rng.integers(0, 3))], "stiffness": float(rng.uniform(800, 3000)),
                "damping": 3.0}
    if kind == "backlash":
        e = {"kind": kind, "joints": [int(rng.integers(0, 3))], "width": float(rng.uniform(0.02, 0.06)),
             "stiffness": 3000.0, "damping": 3.0}
        if contact:               # ``contact`` (cases from CONTACT_FROM on): the contact's stiffness drawn too
            lo, hi = CONTACT_STIFFNESS
            e["stiffness"] = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
        return e
    if kind == "coupling":      # joint j also turned by a neighbour i (any adjacent pair), |c| 0.04-0.12, either sign
        j = int(rng.integers(0, n))
        i = j + 1 if j == 0 else j - 1 if j == n - 1 else j + int(rng.choice([-1, 1]))
        return {"kind": kind, "joints": [j], "from_joint": i,
                "coefficient": float(rng.uniform(0.04, 0.12) * rng.choice([-1.0, 1.0]))}
    raise ValueError(kind)


RATES_HZ = (250.0, 500.0, 1000.0)


def draw_case(seed: int, n: int, base_trials: dict) -> dict:
    """Case ``seed``: ~15 % clean, ~25 % two effects (different kinds, different joints), else one effect; its own
    trajectories, sample rate and controller gains. Cases from ``NEW_KINDS_FROM`` on draw from all kinds, the new
    ones first in every even case (so they get a fair share of the new cases), and from ``SIZED_FROM`` on the
    re-sized thermal drift first in every odd one; earlier cases are unchanged."""
    rng = np.random.default_rng(1000 + seed)
    u = rng.uniform()
    count = 0 if u < 0.15 else (2 if u > 0.75 else 1)
    effects, used = [], set()
    if seed < NEW_KINDS_FROM:
        kinds = [str(k) for k in rng.permutation(KINDS)]
    else:
        kinds = [str(k) for k in rng.permutation(ALL_KINDS)]
        if seed % 2 == 0:
            kinds = [k for k in kinds if k in NEW_KINDS] + [k for k in kinds if k not in NEW_KINDS]
        elif seed >= SIZED_FROM:        # the re-sized thermal drift first in every odd case, for the same reason
            kinds = ["thermal_drift"] + [k for k in kinds if k != "thermal_drift"]
        if seed >= HARD_FROM:           # the hard kinds first, in turn (they replace the schedule above)
            first = HARD_KINDS[seed % len(HARD_KINDS)]
            kinds = [first] + [k for k in kinds if k != first]
    for kind in kinds:
        if len(effects) == count:
            break
        e = draw_effect(rng, kind, n, sized=seed >= SIZED_FROM, fine=seed >= HARD_FROM, contact=seed >= CONTACT_FROM)
        if e["joints"][0] in used:
            continue
        used.add(e["joints"][0])
        effects.append(e)
    trials = copy.deepcopy(base_trials)
    for name in ("excitation", "validation"):
        t = trials[name]
        t["seed"] = int(rng.integers(0, 10_000))
        t["amplitude"] = float(t["amplitude"] * rng.uniform(0.8, 1.1))
        t["center"] = [float(c + rng.uniform(-0.2, 0.2)) for c in t["center"]]
        t["period_s"] = float(t["period_s"] * rng.uniform(0.7, 1.4))
        t["harmonics"] = int(rng.integers(3, 7))
    gain = float(rng.uniform(0.6, 1.6))
    cycle_hz = float(rng.choice(RATES_HZ))
    if seed >= SIZED_FROM and cycle_hz == 250.0:
        gain = min(gain, 1.0)
    ctl = trials["control"]
    for key in ("kp", "kd", "ki"):
        ctl[key] = [float(x * gain) for x in ctl[key]]
    return {"seed": seed, "effects": effects, "cycle_hz": cycle_hz,
            "trials": {k: trials[k] for k in ("excitation", "validation", "control")}}


def bench_model(out: Path, robot) -> Path | None:
    """OUT/model: the model every simulator bench diagnoses with, made once. The simulated Js-2 records the
    identification trials (static, velocity, acceleration, validation; no hidden effect) into
    OUT/clean_session.mcap, and js2-identify (mixed method) identifies it; each step is skipped when its output is
    there. None when js2-identify fails."""
    from identification.cli.identify import main as identify_main

    out.mkdir(parents=True, exist_ok=True)
    session = out / "clean_session.mcap"
    if not session.is_file():
        print("recording the clean identification session ...", flush=True)
        from hil_sim.direct import DirectDriveGroup
        from hil_sim.plant import Plant
        from js2io.session import run_trials

        with DirectDriveGroup(robot, plant=Plant(robot, seed=0), seed=0) as group:
            run_trials(group, robot, ["static", "velocity", "acceleration", "validation"], session)
    model = out / "model"
    if not (model / "model.yaml").is_file():
        print("identifying the model (mixed method) ...", flush=True)
        if identify_main([str(session), "-o", str(model), "-q", "--no-report"]) != 0:
            return None
    return model


def record(robot, path: Path, effects, trials_cfg: dict, seed: int, cycle_hz: float | None = None) -> None:
    from hil_sim.direct import DirectDriveGroup
    from hil_sim.plant import Plant
    from js2io.session import run_trials

    plant = Plant(robot, seed=seed, effects=effects)
    with DirectDriveGroup(robot, plant=plant, seed=seed, cycle_hz=cycle_hz) as group:
        res = run_trials(group, robot, ["excitation", "validation"], path, trials_config=trials_cfg, seed=seed)
    if res.aborted:
        raise RuntimeError(f"simulation aborted: {res.reason}")


PARAMS = {"stribeck": ["velocity", "shape"], "cogging": ["periods_per_rev", "amplitude"], "payload_change": ["mass"],
          "thermal_drift": ["time_constant"], "load_dependent_friction": ["coefficient"],
          "asymmetric_friction": ["negative_scale"], "joint_elasticity": ["stiffness"], "backlash": ["width"],
          "coupling": ["coefficient"], "torque_offset": ["offset"]}


def param_errors(true: dict, found: dict) -> dict:
    out = {}
    for p in PARAMS[true["kind"]]:
        if p in true and p in found and true[p]:
            out[p] = {"true": true[p], "found": found[p], "rel_error": abs(found[p] - true[p]) / abs(true[p])}
    if true["kind"] == "thermal_drift":     # only heating x friction_per_kelvin is observable from torques
        heat = "friction_power_heating" if true.get("friction_power_heating") else "heating"
        found_heat = "friction_power_heating" if found.get("friction_power_heating") else "heating"
        out["heat source (1 = wrong)"] = {"true": heat, "found": found_heat, "rel_error": float(heat != found_heat)}
        if heat == found_heat:
            prod = true[heat] * true["friction_per_kelvin"]
            got = found[heat] * found["friction_per_kelvin"]
            out["heating*friction_per_kelvin"] = {"true": prod, "found": got, "rel_error": abs(got - prod) / prod}
    return out


def _min_gain() -> float:
    from diagnosis.run import DiagnoseOptions

    return DiagnoseOptions.min_gain


MIN_VISIBLE = _min_gain()   # the diagnosis' own acceptance floor (--min-gain's default): gain on the term's motors


def visibility(rec: Path, model: Path, effects: list[dict], out: Path) -> list[float]:
    """How much of the residual each concealed effect makes, on its own: the recording replayed through the model
    alone and through the model plus that one effect at its true parameters (``hil_sim.replay``, inverse: the
    recorded motion, the simulator's own effect code); 1 - RMS_with^2 / RMS_model^2 of the torque-band residual on
    the effect's motor (a payload: the motor it changes most), with the simulator's sliding friction at rest too
    (``hold_at_rest=False``: the yardstick the committed rows were measured with). Below MIN_VISIBLE the exact effect removes less of
    its motor's residual than the diagnosis requires of any term: no method with that floor can name it. Negative:
    the exact effect does not reproduce the recording sample by sample (a backlash's impacts on a joint without
    gravity: the link's place in the gap is chaotic), which says nothing about whether it shows."""
    import yaml

    from hil_sim.replay import replay_recording

    vis = []
    for i, e in enumerate(effects):
        path = out / f"truth_{rec.stem}_{i}.yaml"
        path.write_text(yaml.safe_dump({"effects": [e]}))
        rep = replay_recording(rec, model, path, forward=False, hold_at_rest=False)
        path.unlink(missing_ok=True)
        g = 1.0 - (rep.rms("effects") / rep.rms("model")) ** 2
        vis.append(float(np.nanmax(g) if e["kind"] in ("payload_change", "coupling") else g[e["joints"][0]]))
    return vis


def visible(v: float | None) -> bool:
    """Counted as visible unless the exact effect changes its motor's residual by less than MIN_VISIBLE."""
    return v is None or abs(v) >= MIN_VISIBLE


def _kept_visibility(case: dict, rec: Path, sources: list[Path] | None) -> list[float] | None:
    """The visibility of ``case`` from an earlier run's row (``--visibility-from DIR``, the first DIR that has it):
    it depends only on the recording and the model, so it is taken when that row is of the same draw and was
    written after the recording (made from this very file); otherwise None (it is computed again). A case read
    every k-th cycle (``log_every``) takes the visibility of its recording at the drawn rate (``rec``): how much
    of its motor's residual the effect makes on the arm, which the slower log samples."""
    drawn = _drawn(case)
    for source in [sources] if isinstance(sources, Path) else sources or []:
        old = source / f"case_{case['seed']:03d}.json"
        if not (old.is_file() and rec.is_file()) or old.stat().st_mtime < rec.stat().st_mtime:
            continue
        row = json.loads(old.read_text())
        if row.get("case") != drawn or row.get("visibility") is None:
            continue
        return row["visibility"]
    return None


def _drawn(case: dict) -> dict:
    """``case`` as drawn (without ``log_every``), as an earlier run's row stores it (through JSON)."""
    return json.loads(json.dumps({k: v for k, v in case.items() if k != "log_every"}))


def at_log_rate(case: dict, log_hz: float | None) -> dict:
    """``case`` diagnosed on its recording read every k-th SYNC cycle, k = round(drawn rate / log_hz)
    (``log_every``; ``--log-hz``): the drives and the host's loop run at the drawn rate, the log is written slowly,
    as real arms are logged (a KUKA's FRI at 100-200 Hz). The effects, trajectories and gains are as drawn.

    (Running the loop itself at 100 Hz is not this: with the drawn gains, tuned for 250-1000 Hz, a clean arm
    chatters there, 24-100 mrad at 9.5 Hz on every joint (case 104; 0.1-0.6 mrad at its drawn 500 Hz), so such a
    recording tests a controller that no one would run.)"""
    if log_hz is None:
        return case
    return dict(case, log_every=max(1, int(round(case["cycle_hz"] / float(log_hz)))))


def _kept_recording(case: dict, sources: list[Path] | None, rec: Path) -> bool:
    """Link the kept recording of ``case`` from the first of ``sources`` that has it (earlier runs with
    --keep-recordings: ``--recordings-from``) to ``rec``, when that run's row is of the same draw."""
    if rec.is_file():
        return True
    drawn = _drawn(case)
    for source in sources or []:
        old_rec = source / "runs" / rec.name
        old_row = source / f"case_{case['seed']:03d}.json"
        if not (old_rec.is_file() and old_row.is_file()):
            continue
        if json.loads(old_row.read_text()).get("case") != drawn:
            continue
        rec.parent.mkdir(parents=True, exist_ok=True)
        try:
            rec.hardlink_to(old_rec)
        except OSError:
            import shutil
            shutil.copyfile(old_rec, rec)
        return True
    return False


def run_case(case: dict, model: Path, robot, base_cfg: dict, out: Path, keep: bool = False,
             rediagnose: bool = False, record_only: bool = False, visibility_from: list[Path] | None = None,
             recordings_from: list[Path] | None = None) -> dict | None:
    """Simulate (unless its recording is kept) and diagnose case ``case``; cached in OUT/case_NNN.json, valid while
    the case's draw is unchanged. A case with ``log_every`` (:func:`at_log_rate`) is diagnosed on its recording read
    every k-th cycle (``js2spec.resample.decimate_log``, OUT/runs/case_NNN_everyK.mcap)."""
    from diagnosis.run import diagnose
    from js2spec.resample import decimate_log

    res_path = out / f"case_{case['seed']:03d}.json"
    rec = out / "runs" / f"case_{case['seed']:03d}.mcap"
    every = int(case.get("log_every", 1))
    if res_path.is_file() and not rediagnose:
        row = json.loads(res_path.read_text())
        if row.get("case") == json.loads(json.dumps(case)):
            if "visibility" not in row and rec.is_file():          # a result from before the column: add it
                row["visibility"] = visibility(rec, model, case["effects"], out)
                res_path.write_text(json.dumps(row, default=float))
            return row
    rec.parent.mkdir(parents=True, exist_ok=True)
    sim_s = None
    if not _kept_recording(case, recordings_from, rec):
        cfg = copy.deepcopy(base_cfg)
        cfg.update(copy.deepcopy(case["trials"]))
        t0 = time.time()
        record(robot, rec, case["effects"], cfg, seed=case["seed"], cycle_hz=case.get("cycle_hz"))
        sim_s = round(time.time() - t0, 1)
    if record_only:
        return None
    vis = _kept_visibility(case, rec, visibility_from)
    if every > 1:
        slow = rec.with_name(f"{rec.stem}_every{every}.mcap")
        if not slow.is_file():
            decimate_log(rec, slow, every)
        if not keep:
            rec.unlink(missing_ok=True)
        rec = slow
    if vis is None:
        vis = visibility(rec, model, case["effects"], out)
    t1 = time.time()
    res = diagnose(model, rec)
    t2 = time.time()
    named = [{"kind": f["kind"], "joint": int(f["effect"]["joints"][0]), "effect": f["effect"],
              "report_gain": f["holdout_gain"], "select_gain": f["select_gain"], "fit_gain": f["fit_gain"],
              "select_gain_all": f["select_gain_all"], "select_gain_capped": f["select_gain_capped"],
              "hyper": f["hyper"], **_alike(f)} for f in res.findings()]
    unexplained = res.unexplained()
    row = {"seed": case["seed"], "case": case, "effects": case["effects"], "cycle_hz": case.get("cycle_hz") / every,
           "named": named, "unexplained": [u["joint_index"] for u in unexplained],
           "unexplained_references": [u["reference"] for u in unexplained], "visibility": vis,
           "sim_s": sim_s, "diagnose_s": round(t2 - t1, 1)}
    res_path.write_text(json.dumps(row, default=float))
    if not keep:
        rec.unlink(missing_ok=True)
    return row


def _key(f: dict, joint: int) -> tuple:
    """What must match for a name to be right: kind and joint (link for a payload), and for a coupling the joint it
    comes from as well."""
    return (f["kind"], joint) + ((f.get("from_joint"),) if f["kind"] == "coupling" else ())


def _alike(finding: dict) -> dict:
    """A bench row's record of the links a named payload's reading cannot be told apart from (the diagnosis' own
    ``links_alike_index``, :meth:`diagnosis.library.PayloadChange.resolve`): empty when it names none."""
    return {"links_alike": finding["links_alike_index"]} if finding.get("links_alike_index") else {}


def _alike_hits(row: dict) -> tuple[int, int]:
    """(true payloads named on another link that the named reading says it cannot tell apart from it, those names):
    counted apart from the strict score, which wants the very link."""
    named = {_key(f["effect"], f["joint"]) for f in row["named"]}
    true_keys = {_key(e, e["joints"][0]) for e in row["effects"]}
    found = names = 0
    used = set()
    for e in row["effects"]:
        if e["kind"] != "payload_change" or _key(e, e["joints"][0]) in named:
            continue
        g = next((k for k, f in enumerate(row["named"]) if f["kind"] == "payload_change" and k not in used
                  and e["joints"][0] in f.get("links_alike", ())), None)
        if g is not None:
            used.add(g)
            found += 1
            names += _key(row["named"][g]["effect"], row["named"][g]["joint"]) not in true_keys
    return found, names


def score(rows: list[dict]) -> dict:
    # a concealed torque offset is the real-data bench's (bench_diagnose_real): its row only where one is concealed
    labels = ["none"] + list(ALL_KINDS) + [k for k in NAMED if k not in ALL_KINDS
                                           and any(e["kind"] == k for r in rows for e in r["effects"])]
    cols = ["nothing"] + list(NAMED)
    conf = {r: {c: 0 for c in cols} for r in labels}
    false_names = {k: 0 for k in NAMED}
    hits = total = clean_ok = clean = 0
    vis_hits = vis_total = 0
    hidden = []                          # (case, kind, joint, visibility, found) of effects below MIN_VISIBLE
    missed = []                          # (case, rate, kind, joint, visibility, named there) of visible misses
    errors = {k: [] for k in NAMED}
    wrong_source = 0
    for row in rows:
        named = {_key(f["effect"], f["joint"]): f for f in row["named"]}
        if not row["effects"]:
            clean += 1
            clean_ok += not named
            if not named:
                conf["none"]["nothing"] += 1
            for f in row["named"]:
                conf["none"][f["kind"]] += 1
            continue
        true_keys = set()
        vis = row.get("visibility") or [None] * len(row["effects"])
        for e, v in zip(row["effects"], vis):
            j = e["joints"][0]
            true_keys.add(_key(e, j))
            total += 1
            f = named.get(_key(e, j))
            if f is None and e["kind"] == "coupling":
                wrong_source += any(g["kind"] == "coupling" and g["joint"] == j for g in row["named"])
            if visible(v):
                vis_total += 1
                vis_hits += f is not None
                if f is None:
                    missed.append((row["seed"], row.get("cycle_hz") or 500, e["kind"], j, v,
                                   [g["kind"] for g in row["named"] if g["joint"] == j]))
            else:
                hidden.append((row["seed"], e["kind"], j, v, f is not None))
            if f is not None:
                hits += 1
                conf[e["kind"]][e["kind"]] += 1
                errors[e["kind"]].append(param_errors(e, f["effect"]))
            else:
                on_j = [g for g in row["named"] if g["joint"] == j]
                conf[e["kind"]][on_j[0]["kind"] if on_j else "nothing"] += 1
        for key, f in named.items():
            if key not in true_keys:
                false_names[f["kind"]] += 1
    alike = [_alike_hits(row) for row in rows]
    return {"confusion": conf, "false_names": false_names, "coupling_wrong_source": wrong_source,
            "alike_found": sum(a for a, _ in alike), "alike_names": sum(b for _, b in alike),
            "effects_found": hits, "effects": total,
            "effect_rate": hits / total if total else float("nan"),
            "visible_found": vis_hits, "visible": vis_total,
            "visible_rate": vis_hits / vis_total if vis_total else float("nan"), "below_floor": hidden,
            "visible_missed": missed,
            "clean_none": clean_ok, "clean": clean,
            "clean_rate": clean_ok / clean if clean else float("nan"), "param_errors": errors}


def print_report(s: dict, rows: list[dict]) -> None:
    cols = ["nothing"] + list(NAMED)
    short = {"torque_offset": "offs", "nothing": "nothing", "stribeck": "strib", "cogging": "cogg", "payload_change": "payl",
             "thermal_drift": "therm", "load_dependent_friction": "loadf", "asymmetric_friction": "asym",
             "joint_elasticity": "elast", "backlash": "backl", "coupling": "coupl"}
    print(f"cases: {len(rows)} ({s['clean']} clean, {s['effects']} concealed effects)")
    print("| concealed \\ named on that joint | " + " | ".join(short[c] for c in cols) + " |")
    print("|---" * (len(cols) + 1) + "|")
    for r, d in s["confusion"].items():
        if sum(d.values()):
            print(f"| {r} | " + " | ".join(str(d[c]) if d[c] else "." for c in cols) + " |")
    print("false names (named where that kind was not concealed): "
          + (", ".join(f"{k} {v}" for k, v in s["false_names"].items() if v) or "none"))
    if s.get("coupling_wrong_source"):
        print(f"couplings named on the right joint from the wrong joint (counted missed, and a false name): "
              f"{s['coupling_wrong_source']}")
    for row in rows:                      # each false name with its report gain (a true one's for comparison)
        true_keys = {_key(e, e["joints"][0]) for e in row["effects"]}
        for f in row["named"]:
            if _key(f["effect"], f["joint"]) not in true_keys:
                print(f"  false name: case {row['seed']:3d} ({row.get('cycle_hz') or 500:g} Hz) {f['kind']} on joint "
                      f"{f['joint']}, report gain {f['report_gain']:.2f}"
                      + (" (clean case)" if not row["effects"] else ""))
    gains = {}
    for row in rows:
        true_keys = {_key(e, e["joints"][0]) for e in row["effects"]}
        for f in row["named"]:
            if _key(f["effect"], f["joint"]) in true_keys:
                gains.setdefault(f["kind"], []).append(f["report_gain"])
    print("report gain of the right names: " + ", ".join(f"{k} {min(v):.2f}-{max(v):.2f}" for k, v in gains.items()))
    print(f"right effect and joint: {s['effects_found']}/{s['effects']} = {s['effect_rate']:.0%}; "
          f"clean cases named nothing: {s['clean_none']}/{s['clean']} = {s['clean_rate']:.0%}")
    print(f"right effect and joint, effects the residual shows (exact effect removes >= {MIN_VISIBLE:.0%} of its "
          f"motor's residual): {s['visible_found']}/{s['visible']} = {s['visible_rate']:.0%}")
    if s.get("alike_found"):
        found = s["effects_found"] + s["alike_found"]
        print(f"counting a payload named on another link that the diagnosis reports it cannot tell apart from the "
              f"true one (links_alike): {found}/{s['effects']} = {found / s['effects']:.0%}, "
              f"{sum(s['false_names'].values()) - s['alike_names']} false names")
    for seed, kind, j, v, found in s["below_floor"]:
        print(f"  below the floor: case {seed:3d} {kind} on joint {j}: the exact effect removes {v:.1%} "
              f"({'named anyway' if found else 'not named'})")
    for seed, rate, kind, j, v, on_j in s["visible_missed"]:     # the misses the residual does show
        print(f"  missed: case {seed:3d} ({rate:g} Hz) {kind} on joint {j}"
              + (f", the exact effect removes {v:.0%}" if v is not None else "")
              + f"; named there: {', '.join(on_j) or 'nothing'}")
    for kind, errs in s["param_errors"].items():
        by = {}
        for e in errs:
            for p, v in e.items():
                by.setdefault(p, []).append(v["rel_error"])
        for p, v in by.items():
            if p.endswith("(1 = wrong)"):
                print(f"  {kind:<24} {p[:-12]:<28} wrong in {int(np.sum(v))} of {len(v)}")
            else:
                print(f"  {kind:<24} {p:<28} median error {np.median(v):.1%}, max {np.max(v):.1%} (n = {len(v)})")
    sim = [r["sim_s"] for r in rows if r.get("sim_s")]
    diag = [r["diagnose_s"] for r in rows if r.get("diagnose_s")]
    if diag:
        print(f"time per case (median): diagnose {np.median(diag):.0f} s"
              + (f", simulate {np.median(sim):.0f} s" if sim else ""))


def print_thermal_sizes(rows: list[dict], out: Path) -> None:
    """How much each concealed thermal drift changes friction at steady state, heating * alpha * mean(I^2) of the
    kept recording's motor current: a drift of a few per cent is below what the residual can show."""
    from js2spec.log import read_log

    for row in rows:
        rec = out / "runs" / f"case_{row['seed']:03d}.mcap"
        for e in row["effects"]:
            if e["kind"] != "thermal_drift" or not rec.is_file():
                continue
            j = e["joints"][0]
            i2 = float(np.nanmean(np.asarray(read_log(rec).feedback.motor_current, float)[:, j] ** 2))
            found = any(f["kind"] == "thermal_drift" and f["joint"] == j for f in row["named"])
            if e.get("friction_power_heating"):
                print(f"  thermal_drift case {row['seed']:3d} joint {j}: heated by friction power "
                      f"({e['friction_power_heating']:.3g} K/W, alpha {e['friction_per_kelvin']:.3g}/K; drawn for a "
                      f"20-60 % friction change) ({'found' if found else 'missed'})")
                continue
            print(f"  thermal_drift case {row['seed']:3d} joint {j}: mean I^2 {i2:.3g} A^2, steady friction change "
                  f"{100 * e['heating'] * e['friction_per_kelvin'] * i2:.1f} % ({'found' if found else 'missed'})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=48, help="number of cases (default 48)")
    ap.add_argument("--first", type=int, default=0, help="seed of the first case (default 0)")
    ap.add_argument("--out", type=Path, default=Path("runs/bench_diagnose"))
    ap.add_argument("--keep-recordings", action="store_true", help="keep each case's recording in OUT/runs/")
    ap.add_argument("--rediagnose", action="store_true",
                    help="diagnose the kept recordings again (ignore the cached results; implies --keep-recordings)")
    ap.add_argument("--record-only", action="store_true", help="simulate and keep the recordings, do not diagnose")
    ap.add_argument("--visibility-from", type=Path, metavar="DIR", action="append",
                    help="with --rediagnose or --recordings-from: take each case's visibility from DIR/case_NNN.json "
                         "(an earlier run on the same recordings: same draw, row written after the recording) "
                         "instead of replaying every effect again (about half of a rerun's time); may be given "
                         "several times. With --log-hz, the visibility at the drawn rate")
    ap.add_argument("--from-json", type=Path, metavar="BENCH_JSON",
                    help="print the report of a saved bench.json (e.g. docs/bench/diagnose-bench-all-2026-11-24.json) "
                         "without simulating or diagnosing anything")
    ap.add_argument("--log-hz", type=float, metavar="HZ",
                    help="diagnose every case's recording read every k-th SYNC cycle, k = round(drawn rate / HZ): "
                         "the drives' loop as drawn, logged slowly as real arms are (250 Hz cases: k = 2, 125 Hz)")
    ap.add_argument("--recordings-from", type=Path, metavar="DIR", action="append",
                    help="take each case's recording from DIR/runs/ (an earlier run with --keep-recordings, same "
                         "draw) instead of simulating it again; may be given several times")
    a = ap.parse_args(argv)
    if a.log_hz is not None and not 10.0 <= a.log_hz <= 10_000.0:
        print(f"bench_diagnose: error: --log-hz {a.log_hz:g} is not a logging rate (10-10000 Hz)", file=sys.stderr)
        return 2
    if a.from_json is not None:
        try:
            rows = json.loads(a.from_json.read_text())["rows"]
        except (OSError, ValueError, KeyError, TypeError) as e:
            print(f"error: {a.from_json}: not a bench.json written by this script ({e}); run it without --from-json "
                  "to make one", file=sys.stderr)
            return 2
        print_report(score(rows), rows)
        return 0
    keep = a.keep_recordings or a.rediagnose or a.record_only
    from js2io.session import _default_trials
    from js2io.trials import load_trials_config
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    base_cfg = load_trials_config(robot.trials_path or _default_trials())
    model = bench_model(a.out, robot)
    if model is None:
        return 1
    rows = []
    n = robot.drives.n
    for seed in range(a.first, a.first + a.cases):
        case = at_log_rate(draw_case(seed, n, base_cfg), a.log_hz)
        row = run_case(case, model, robot, base_cfg, a.out, keep, a.rediagnose, a.record_only, a.visibility_from,
                       a.recordings_from)
        truth = ", ".join(f"{e['kind']}@{e['joints'][0]}" for e in case["effects"]) or "clean"
        if row is None:
            print(f"case {seed:3d}: recorded ({truth}, {case['cycle_hz']:g} Hz)", flush=True)
            continue
        rows.append(row)
        named = ", ".join(f"{f['kind']}@{f['joint']}" for f in row["named"]) or "nothing"
        print(f"case {seed:3d}: {row['cycle_hz']:5g} Hz concealed {truth:<50} named {named}", flush=True)
    if not rows:
        return 0
    s = score(rows)
    print_report(s, rows)
    print_thermal_sizes(rows, a.out)
    (a.out / "bench.json").write_text(json.dumps({"score": s, "rows": rows}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
