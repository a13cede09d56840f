#!/usr/bin/env python3
"""Benchmark js2-diagnose on real recordings with randomised concealed effects: confusion matrix, parameter errors.

The simulator bench (scripts/bench_diagnose.py) draws its cases from js2's own simulator; this one draws them on
real noise and real unmodelled friction, which nobody on the team made:

1. the KUKA LWR4+ recordings (../shared/data/real/kuka_lwr4: 200 Hz, joint torque sensors, K = I, no trial
   labels) through js2-import, and the plain ``js2-identify kuka_1.mcap`` model (prove_diagnosis_real.py's);
2. case k (seed k, fixed): kuka_2 or kuka_3 (neither identified the model), 0, 1 or 2 effects at random kinds,
   joints and sizes, their torque added along the recorded motion (positions, the provider's velocities, the
   recorded torque) in hil_sim's form of that kind:

   - ``stribeck``: a hump h sgn(v) exp(-(|v| / v_s)^delta), v_s 0.05-0.3 rad/s, delta 1 or 2;
   - ``cogging``: A sin(p q + phi), p 8-40 per revolution (K = I: motor = joint);
   - ``asymmetric_friction``: the model's Coulomb friction scaled by 1.3-2.0 (or 0.4-0.7) when moving backwards;
   - ``load_dependent_friction``: mu |tau| sgn(v), tau the joint's recorded torque, mu set by the size below (not
     drawn in a range: over seeds 0-179 0.011-3.29; 7 of 21 at 0.5 or more, on lwr_5 and lwr_7 whose recorded
     torque is small, which js2-diagnose refuses as no gear's friction);
   - ``thermal_drift``: the model's friction (B v + f_c sgn v) scaled by alpha dT, dT first order (time constant
     4-12 s, under the 10 s the diagnosis looks for first) in the friction power |f v|, its change set by the size
     below (over seeds 0-179 the friction at the recording's end is changed by 28 % to 5.5x);
   - ``torque_offset``: a constant;
   - ``payload_change``: a point mass of 0.5-2.5 kg at a random centre (within 6 cm) on link 4-7, its torque by
     RNEA along the recorded motion.

   The friction-law and ripple effects are sized against the model's own error on their joint: the effect's RMS
   is 0.6-2.5 times the clean recording's torque-band residual RMS there (a payload is not sized). Visibility is
   measured as in the simulator bench: the share of the effect's motor's residual (torque band, whole recording)
   the exact effect removes;
3. js2-diagnose with its defaults names what it finds; scored as the simulator bench scores (same kind on the same
   joint; a payload on the same link).

    .venv/bin/python scripts/bench_diagnose_real.py [--cases 40] [--first 0] [--out runs/bench_diagnose_real]
        [--data ../shared/data/real] [--rediagnose] [--model runs/bench_diagnose_real/model]
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, HERE / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


prove = _script("prove_diagnosis_real")
sim_bench = _script("bench_diagnose")

KINDS = ("stribeck", "cogging", "asymmetric_friction", "load_dependent_friction", "thermal_drift", "torque_offset",
         "payload_change")
RECORDINGS = (2, 3)             # kuka_<which>; kuka_1 identified the model
SIZE = (0.6, 2.5)               # effect RMS / clean residual RMS on its joint (torque band)


def _first_order(x: np.ndarray, t: np.ndarray, tau: float) -> np.ndarray:
    """y' = (x - y) / tau from y(0) = 0, exact for x held over each step (the thermal rise)."""
    y = np.zeros_like(x)
    for i in range(1, len(x)):
        a = np.exp(-(t[i] - t[i - 1]) / tau)
        y[i] = a * y[i - 1] + (1 - a) * x[i - 1]
    return y


def effect_torque(e: dict, t, q, v, ddq, tau, fc, fv, urdf: Path, joints: list[str]) -> np.ndarray:
    """The joint torque (N, n) effect ``e`` adds along the recorded motion (K = I: motor side too), unscaled for the
    sized kinds (scaled by ``e['scale']`` when present)."""
    out = np.zeros_like(q)
    j = e["joints"][0]
    k = e["kind"]
    if k == "payload_change":
        return prove.payload_torque(urdf, joints, q, v, ddq, e["mass"], e["com"], link_joint=j)
    if k == "stribeck":
        col = prove._sgn_moving(v[:, j]) * np.exp(-(np.abs(v[:, j]) / e["velocity"]) ** e["shape"])
    elif k == "cogging":
        col = np.sin(e["periods_per_rev"] * q[:, j] + e["phase"])
    elif k == "asymmetric_friction":
        col = np.where(v[:, j] < -0.01, -(e["negative_scale"] - 1.0) * fc[j], 0.0)
    elif k == "load_dependent_friction":
        col = np.abs(tau[:, j]) * prove._sgn_moving(v[:, j])
    elif k == "thermal_drift":
        f = fv[j] * v[:, j] + fc[j] * prove._sgn_moving(v[:, j])
        rise = _first_order(np.abs(f * v[:, j]), t, e["time_constant"])
        col = rise * f                                      # alpha * heating applied by the scale
    elif k == "torque_offset":
        col = np.full(len(t), e["sign"])
    else:
        raise ValueError(k)
    out[:, j] = col * e.get("scale", 1.0)
    return out


def draw_case(seed: int, n: int) -> dict:
    """Case ``seed``: ~15 % clean, ~25 % two effects (different kinds and joints), else one; its recording."""
    rng = np.random.default_rng(7000 + seed)
    u = rng.uniform()
    count = 0 if u < 0.15 else (2 if u > 0.75 else 1)
    which = int(rng.choice(RECORDINGS))
    effects, used = [], set()
    for kind in (str(k) for k in rng.permutation(KINDS)):
        if len(effects) == count:
            break
        if kind == "payload_change":
            j = int(rng.integers(3, n))
            e = {"kind": kind, "joints": [j], "mass": float(rng.uniform(0.5, 2.5)),
                 "com": [float(x) for x in rng.uniform(-0.06, 0.06, 3)]}
        else:
            j = int(rng.integers(0, n))
            e = {"kind": kind, "joints": [j]}
            if kind != "asymmetric_friction":      # sized by its own scale on the model's Coulomb friction
                e["size"] = float(rng.uniform(*SIZE))
            if kind == "stribeck":
                e.update(velocity=float(rng.uniform(0.05, 0.3)), shape=float(rng.choice([1.0, 2.0])))
            elif kind == "cogging":
                e.update(periods_per_rev=float(rng.integers(8, 41)), phase=float(rng.uniform(0, 2 * np.pi)))
            elif kind == "asymmetric_friction":
                e["negative_scale"] = float(rng.uniform(1.3, 2.0) if rng.uniform() < 0.7 else rng.uniform(0.4, 0.7))
            elif kind == "thermal_drift":
                e["time_constant"] = float(rng.uniform(4.0, 12.0))
            elif kind == "torque_offset":
                e["sign"] = float(rng.choice([-1.0, 1.0]))
        if j in used:
            continue
        used.add(j)
        effects.append(e)
    return {"seed": seed, "recording": which, "effects": effects}


class Workspace:
    """The imported KUKA recordings, the plain model, and per recording its clean residual (torque band)."""

    def __init__(self, data: Path, out: Path, logs: Path | None = None, model: Path | None = None):
        """``logs``, ``model``: the imported recordings' folder and the model, when already made (read only);
        otherwise both are made in ``out``."""
        from identification.examples.real_arms import kuka_paths, load_kuka
        from js2spec.drives import load_drives
        from js2spec.model import load_model

        self.data, self.out = data, out
        if logs is None:
            prove.import_logs(data, out)
            logs = out
        if model is None:       # identified from kuka_1 (cached in OUT/model: the plain command takes minutes)
            model = prove.identify(Path(logs) / "kuka_1.mcap", out / "model")
        self.logs, self.model = Path(logs), Path(model)
        mdl = load_model(self.model)
        self.fc, self.fv = np.asarray(mdl.friction_coulomb, float), np.asarray(mdl.friction_viscous, float)
        _, self.urdf, drives = kuka_paths(data)
        self.joints = list(load_drives(drives).joints)
        self.load_kuka = load_kuka
        self._clean = {}

    def clean(self, which: int):
        """(recording, raw arrays, residual data of the clean recording) for kuka_<which>."""
        if which not in self._clean:
            from diagnosis.residual import residual_data
            from js2spec.log import read_log
            from js2spec.model import load_model

            rec, raw = self.load_kuka(self.data, which)
            rd = residual_data(load_model(self.model), read_log(self.logs / f"kuka_{which}.mcap"))
            self._clean[which] = (rec, raw, rd)
        return self._clean[which]


def sized(case: dict, ws: Workspace) -> tuple[list[dict], np.ndarray, list[float]]:
    """The case's effects with their sizes resolved (``scale``, and the hil_sim parameters that follow from it),
    their joint torque summed (N, n), and each one's visibility on the clean recording's residual."""
    rec, raw, rd = ws.clean(case["recording"])
    t, q, v, tau = rec.t, raw["positions"], raw["velocities"], rec.torque
    res = np.nan_to_num(rd.residual)
    m = rd.mask
    total, effects, vis = np.zeros_like(tau), [], []
    for e in case["effects"]:
        e = dict(e)
        j = e["joints"][0]
        d = effect_torque(e, t, q, v, raw["accelerations"], tau, ws.fc, ws.fv, ws.urdf, ws.joints)
        if "size" in e:
            r = float(np.sqrt(np.mean(res[m[:, j], j] ** 2)))
            own = float(np.sqrt(np.mean(d[m[:, j], j] ** 2)))
            scale = e["size"] * r / own if own > 0 else 0.0
            d = d * scale
            e["scale"] = scale
            if e["kind"] == "stribeck":
                e["static"] = float(ws.fc[j] + scale)          # the hump's top: f_c + h
            elif e["kind"] == "cogging":
                e["amplitude"] = scale
            elif e["kind"] == "load_dependent_friction":
                e["coefficient"] = scale
            elif e["kind"] == "thermal_drift":
                e["friction_per_kelvin"] = 0.01
                e["friction_power_heating"] = scale / 0.01
                e["heating"] = 0.0
            elif e["kind"] == "torque_offset":
                e["offset"] = e["sign"] * scale
        low = rd.lowpass(d)
        motors = [j] if e["kind"] != "payload_change" else list(range(d.shape[1]))
        gains = []
        for k in motors:
            base = float(np.mean(res[m[:, k], k] ** 2))
            with_e = float(np.mean((res[m[:, k], k] + low[m[:, k], k]) ** 2))
            gains.append(1.0 - base / with_e if with_e > 0 else 0.0)
        vis.append(float(max(gains)))
        total += d
        effects.append(e)
    return effects, total, vis


def run_case(case: dict, ws: Workspace, out: Path, rediagnose: bool = False) -> dict:
    from diagnosis.run import diagnose
    from identification.examples.real_arms import write_kuka

    res_path = out / f"case_{case['seed']:03d}.json"
    if res_path.is_file() and not rediagnose:
        row = json.loads(res_path.read_text())
        if row.get("case") == json.loads(json.dumps(case)):
            return row
    effects, added, vis = sized(case, ws)
    rec, _, _ = ws.clean(case["recording"])
    rec_e = dataclasses.replace(rec, torque=rec.torque + added)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    log = write_kuka(rec_e, ws.data, out / "runs" / f"case_{case['seed']:03d}.mcap")
    t1 = time.time()
    result = diagnose(ws.model, log)
    t2 = time.time()
    named = [{"kind": f["kind"], "joint": int(f["effect"]["joints"][0]), "effect": f["effect"],
              "report_gain": f["holdout_gain"], **sim_bench._alike(f)} for f in result.findings()]
    row = {"seed": case["seed"], "case": case, "recording": f"kuka_{case['recording']}", "effects": effects,
           "cycle_hz": 200.0, "named": named, "unexplained": [u["joint_index"] for u in result.unexplained()],
           "visibility": vis, "sim_s": None, "diagnose_s": round(t2 - t1, 1)}
    res_path.write_text(json.dumps(row, default=float))
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=40)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("runs/bench_diagnose_real"))
    ap.add_argument("--data", type=Path, default=prove.DEFAULT_DATA)
    ap.add_argument("--rediagnose", action="store_true", help="diagnose again (after a change to the diagnosis)")
    ap.add_argument("--model", type=Path, default=None,
                    help="the plain model of kuka_1 made by an earlier run (its OUT/model; read only): skips the "
                         "identification, which takes minutes (default: OUT/model, made when missing)")
    a = ap.parse_args(argv)
    if not (a.data / "kuka_lwr4").is_dir():
        print(f"bench_diagnose_real: error: {a.data / 'kuka_lwr4'}: not found; pass --data", file=sys.stderr)
        return 2
    if a.model is not None and not (a.model / "model.yaml").is_file():
        print(f"bench_diagnose_real: error: {a.model / 'model.yaml'}: not found; pass the model folder of an earlier "
              "run (OUT/model), or leave --model out to identify one", file=sys.stderr)
        return 2
    a.out.mkdir(parents=True, exist_ok=True)
    ws = Workspace(a.data, a.out, model=a.model)
    rows = []
    for seed in range(a.first, a.first + a.cases):
        case = draw_case(seed, len(ws.joints))
        row = run_case(case, ws, a.out, rediagnose=a.rediagnose)
        rows.append(row)
        got = ", ".join(f"{f['kind']} j{f['joint']}" for f in row["named"]) or "nothing"
        want = ", ".join(f"{e['kind']} j{e['joints'][0]}" for e in row["effects"]) or "nothing"
        print(f"case {seed:3d} {row['recording']}: concealed {want}; named {got} ({row['diagnose_s']} s)",
              file=sys.stderr, flush=True)
    s = sim_bench.score(rows)
    sim_bench.print_report(s, rows)
    (a.out / "bench.json").write_text(json.dumps({"score": s, "rows": rows}, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
