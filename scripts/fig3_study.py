"""When does the simultaneous method make J_4z negative? The paper's Fig. 3 claim as a simulator study.

The paper (Sakamoto et al., Fig. 3): with B and f_c estimated inside the RLS (simultaneous method) B_4 converges
elsewhere than with them fixed from the sequential tests (mixed method), and J_4z — the inertia of link 4 about
axis 4 — converges positive under the mixed method and negative under the simultaneous one.

This script varies the quantities that can decide that sign, on the built-in simulator, through the same commands a
user runs: ``js2-acquire --direct`` (static, velocity, acceleration and validation trials on a variant of
``configs/js2/`` written to a temporary folder) and the identification pipeline of ``js2-identify`` (in-process:
``identification.pipeline.identify``), both methods, several seeds per point:

* J_4z's share of the inertia motor 4 feels, ``share = K44^2 J_4z / (J_a4 + K44^2 M44)`` (M44 at the acceleration
  trial's centre): the axis-4 gear ratio
  (N4; 1:50 on the default arm) and the inertia of the wrist link 4 (WRIST: link 4's inertia tensor scaled, mass
  and centre of mass kept);
* the friction's departure from eq. 1's Coulomb + viscous law (FRICTION): ``eq1`` (none), ``stribeck``,
  ``load`` (load-dependent Coulomb friction), ``asym`` (asymmetric), ``stribeck+load``; on axis 4 only or on every
  axis (AXES ``4`` or ``all``), at the strengths in ``FRICTION`` below;
* the current noise (NOISE: multiple of ``sim_truth.yaml``'s ``current_noise_std``).

The default map (``full_grid``) varies the gear and the friction; the wrist inertia and the noise are knobs of
``--point N4:WRIST:FRICTION:AXES:NOISE`` for further points.

Each point is classified from its seeds (mean ± standard error of the mean over seeds, and the RLS standard errors):

* ``paper``: the paper's result — simultaneous J_4z < 0 and mixed J_4z > 0, each in every seed and by more than
  ``Z`` (= 2) standard errors (the larger of the seed scatter's s.e.m. and one session's RLS std);
* ``agree_positive`` / ``agree_negative``: both methods give the same sign (positive, as the truth; or both negative,
  physically impossible), each resolved from zero by ``Z`` standard errors;
* ``unidentifiable``: at least one method's J_4z is within ``Z`` standard errors of zero or changes sign between
  seeds (its sign is noise, or decided by the session);
* ``opposite``: resolved, different signs, but not in the paper's direction (mixed < 0 < simultaneous).

Outputs (``--out``, default ``runs/fig3_study``): ``map.json`` and ``map.csv`` (one row per point: the knobs, the
truth, per-method mean / seed s.e.m. / mean RLS std of J_4z, B_4, f_c4, the region), and with ``--figdir`` the
paper's Fig. 3 (RLS convergence of J_4z, B_4, f_c4 under both methods, one seed) for the representative point of
each region (the one with the largest J_4z share; ``fig3_study_<region>.png``, ``fig3_study_quick_<region>.png``
with ``--quick``). Logs are kept in ``--out`` and reused when the run is repeated.

    python scripts/fig3_study.py --figdir docs/img            # the map of the README (~16 min of one core)
    python scripts/fig3_study.py --quick                      # the three points the test pins, one seed, short trials
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
DEFAULT_ROBOT = REPO / "configs" / "js2"
PARAMS = ("J_4z", "B_4", "fc_4", "Ja_4")
Z = 2.0

# friction beyond eq. 1, per kind: hil_sim effects (hil_sim/effects.py) with the strengths used in the study.
# stribeck: hump from f_s down to f_c with v_s = 15 rad/s motor (axis 4's sequential speeds are 16-200 rad/s);
# load: f_c and f_s grow by 0.15 N m per N m the gear transmits; asym: negative direction x 0.6.
FRICTION = {
    "eq1": [],
    "stribeck": [{"kind": "stribeck", "velocity": 15.0}],
    "load": [{"kind": "load_dependent_friction", "coefficient": 0.15}],
    "asym": [{"kind": "asymmetric_friction", "negative_scale": 0.6}],
    "stribeck+load": [{"kind": "stribeck", "velocity": 15.0},
                      {"kind": "load_dependent_friction", "coefficient": 0.15}],
}

# the study's trials: configs/js2/trials.yaml with a shorter sequential part (one static pose, four speeds of 0.35 s:
# eq. 5 needs a line, not a dense one); the acceleration trial (what the RLS sees) is the default one
STUDY_TRIALS = {
    "static": {"poses": [[0.6, 0.7, -1.0, 0.8, 0.6, -0.5]]},
    "velocity": {"speed_fractions": [0.1, 0.35, 0.7, 1.0], "steady_s": 0.35},
    "validation": {"periods": 1.0},
}
TRIALS = "static,velocity,acceleration,validation"
# --quick (the test, ~4x cheaper): no static trial (eq. 5's gravity then comes from the regressor's gravity columns
# alone), three speeds, 12 acceleration strokes instead of 20, a 4 s validation motion
QUICK_TRIALS = {"velocity": {"speed_fractions": [0.15, 0.5, 1.0], "steady_s": 0.3},
                "acceleration": {"strokes_per_duration": 3}, "validation": {"periods": 0.5}}
QUICK_TRIAL_NAMES = "velocity,acceleration,validation"


@dataclass(frozen=True)
class Point:
    """One configuration of the arm and its friction (knobs of the study)."""
    gear4: float = 50.0            # axis-4 reduction N4 (q_joint4 = q_motor4 / N4)
    wrist: float = 1.0             # scale of link 4's inertia tensor (URDF)
    friction: str = "eq1"          # key of FRICTION
    friction_axes: str = "4"       # "4" or "all"
    noise: float = 1.0             # x sim_truth current_noise_std

    @property
    def key(self) -> str:
        return (f"N{self.gear4:g}_w{self.wrist:g}_{self.friction.replace('+', '-')}_ax{self.friction_axes}"
                f"_n{self.noise:g}")


@dataclass
class Estimate:
    value: float
    std: float


@dataclass
class RunResult:
    """One seed of one point: per method and parameter the RLS estimate and its standard error."""
    point: Point
    seed: int
    truth: dict
    share: float
    methods: dict = field(default_factory=dict)     # method -> param -> Estimate
    history: dict = field(default_factory=dict)     # method -> (iters, {param: values})
    seconds: float = 0.0


def fail(msg: str) -> None:
    print(f"fig3_study: error: {msg}", file=sys.stderr)
    raise SystemExit(2)


# -- the variant arm ---------------------------------------------------------------------------------------------

def write_robot(folder: Path, point: Point, quick: bool, base: Path = DEFAULT_ROBOT) -> Path:
    """A copy of ``base`` (configs/js2) with the point's gear ratio, wrist inertia, friction and noise."""
    if point.friction not in FRICTION:
        fail(f"unknown friction {point.friction!r} (known: {', '.join(FRICTION)})")
    if folder.exists():
        shutil.rmtree(folder)
    shutil.copytree(base, folder)
    drives = yaml.safe_load((folder / "drives.yaml").read_text())
    K = np.asarray(drives["gear_ratio_matrix"], float)
    K0 = K.copy()
    n = len(K)
    K[3, 3] = 1.0 / point.gear4
    drives["gear_ratio_matrix"] = K.tolist()
    # the same joint-side speed limit on axis 4 whatever its gear
    r = point.gear4 / (1.0 / K0[3, 3])
    drives["limits"]["velocity"][3] = float(min(drives["limits"]["velocity"][3], drives["limits"]["velocity"][3] * r))
    (folder / "drives.yaml").write_text(yaml.safe_dump(drives, sort_keys=False))
    if point.wrist != 1.0:
        import xml.etree.ElementTree as ET

        tree = ET.parse(folder / "robot.urdf")
        link = tree.getroot().find("link[@name='link4']")
        inertia = link.find("inertial/inertia")
        for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz"):
            inertia.set(k, f"{float(inertia.get(k)) * point.wrist:.6g}")
        tree.write(folder / "robot.urdf")
    truth = yaml.safe_load((folder / "sim_truth.yaml").read_text())
    axes = [3] if point.friction_axes == "4" else list(range(n))
    truth["effects"] = [dict(e, joints=axes) for e in FRICTION[point.friction]]
    truth["sensors"]["current_noise_std"] = [float(x) * point.noise for x in truth["sensors"]["current_noise_std"]]
    (folder / "sim_truth.yaml").write_text(yaml.safe_dump(truth, sort_keys=False))
    # trials: axis 4 moves at the default arm's joint-side speeds and accelerations, and its host PID gains follow the
    # inertia motor 4 feels (J_a4 + K44^2 M44 at the acceleration trial's centre) so the loop keeps its bandwidth
    trials = yaml.safe_load((folder / "trials.yaml").read_text())
    felt0 = _felt_inertia(base, trials)
    felt = _felt_inertia(folder, trials)
    for key in ("kp", "kd", "ki"):
        trials["control"][key][3] = float(trials["control"][key][3] * felt / felt0)
    trials["control"]["max_acceleration"][3] = float(trials["control"]["max_acceleration"][3] * r)
    trials["velocity"]["max_speed"][3] = float(min(trials["velocity"]["max_speed"][3],
                                                   trials["velocity"]["max_speed"][3] * r))
    trials["velocity"]["acceleration"][3] = float(trials["velocity"]["acceleration"][3] * r)
    for k, v in list(STUDY_TRIALS.items()) + (list(QUICK_TRIALS.items()) if quick else []):
        trials[k].update(v)
    (folder / "trials.yaml").write_text(yaml.safe_dump(trials, sort_keys=False))
    return folder


def _felt_inertia(folder: Path, trials: dict) -> float:
    """Inertia motor 4 feels (kg m^2, motor side): J_a4 + K44^2 M44(q) at the acceleration trial's centre."""
    import pinocchio as pin

    model = pin.buildModelFromXML((folder / "robot.urdf").read_text())
    data = model.createData()
    q = np.asarray(trials["acceleration"]["center"], float)
    M = pin.crba(model, data, q)
    K = np.asarray(yaml.safe_load((folder / "drives.yaml").read_text())["gear_ratio_matrix"], float)
    ja = yaml.safe_load((folder / "sim_truth.yaml").read_text())["motor_inertia"][3]
    return float(ja + K[3, 3] ** 2 * M[3, 3])


def acquire(robot: Path, seed: int, out: Path, trials: str = TRIALS) -> None:
    """js2-acquire on the in-process simulator (direct: the same drives and trial code, no CAN)."""
    cmd = [sys.executable, "-m", "js2io.cli", "--robot", str(robot), "--direct", "--no-progress", "--trial",
           trials, "--seed", str(seed), "-o", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        out.unlink(missing_ok=True)     # never reuse an aborted session
        said = (r.stdout + r.stderr).strip().splitlines()
        last = [ln for ln in said if "ABORTED" in ln or "error" in ln] or said[-1:] or [f"exit {r.returncode}"]
        fail(f"js2-acquire failed for {robot.name} (seed {seed}): {last[-1]}")


# -- identification ----------------------------------------------------------------------------------------------

def identify_log(log: Path, robot: Path, point: Point, seed: int) -> RunResult:
    """Both methods on one log (what js2-identify runs); the truth (from the variant's files) only for the table."""
    from hil_sim.truth import load_truth
    from identification.pipeline import IdentifyOptions, identify
    from identification.regressor import standard_vector
    from js2spec.robot import load_robot

    ident = identify([log], IdentifyOptions(method="mixed", physical=False))
    tr = load_truth(load_robot(robot))
    beta_true = ident.bp.beta(standard_vector(ident.arm, motor_inertia=tr.motor_inertia, viscous=tr.viscous,
                                              coulomb=tr.coulomb))
    res = RunResult(point=point, seed=seed, truth={}, share=0.0)
    for p in PARAMS:
        i = ident.param_index(p)
        res.truth[p] = float(beta_true[i])
    felt = _felt_inertia(robot, yaml.safe_load((robot / "trials.yaml").read_text()))
    res.share = float(res.truth["J_4z"] / point.gear4 ** 2 / felt)
    for m, mr in ident.methods.items():
        res.methods[m] = {p: Estimate(float(mr.beta[ident.param_index(p)]), float(mr.std[ident.param_index(p)]))
                          for p in PARAMS}
        res.history[m] = (mr.history_iter.tolist(),
                          {p: mr.history[:, ident.param_index(p)].tolist() for p in PARAMS})
    return res


def run_point(point: Point, seeds, out: Path, quick: bool, log=print) -> list[RunResult]:
    results = []
    tmp = Path(tempfile.mkdtemp(prefix="js2_fig3_"))
    try:
        robot = write_robot(tmp / point.key, point, quick)
        for s in seeds:
            t0 = time.perf_counter()
            mcap = out / "logs" / f"{point.key}{'_quick' if quick else ''}_s{s}.mcap"
            mcap.parent.mkdir(parents=True, exist_ok=True)
            if not mcap.is_file():
                acquire(robot, s, mcap, QUICK_TRIAL_NAMES if quick else TRIALS)
            r = identify_log(mcap, robot, point, s)
            r.seconds = time.perf_counter() - t0
            results.append(r)
            j = {m: r.methods[m]["J_4z"] for m in r.methods}
            log(f"  {point.key} seed {s}: J_4z mixed {j['mixed'].value:+.3e} ± {j['mixed'].std:.1e}, "
                f"simultaneous {j['simultaneous'].value:+.3e} ± {j['simultaneous'].std:.1e} "
                f"(truth {r.truth['J_4z']:.3e}); B_4 {r.methods['mixed']['B_4'].value:.3e} / "
                f"{r.methods['simultaneous']['B_4'].value:.3e}  [{r.seconds:.0f} s]")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return results


# -- the map -----------------------------------------------------------------------------------------------------

def summarise(results: list[RunResult], z: float = Z) -> dict:
    """Mean over seeds, its standard error (seed scatter and RLS std), and the region of one point."""
    r0 = results[0]
    row = {**asdict(r0.point), "key": r0.point.key, "seeds": [r.seed for r in results], "share": r0.share}
    for p in PARAMS:
        row[f"{p}_truth"] = r0.truth[p]
    for m in ("mixed", "simultaneous"):
        for p in PARAMS:
            v = np.array([r.methods[m][p].value for r in results])
            s = np.array([r.methods[m][p].std for r in results])
            k = len(v)
            sem_seed = float(v.std(ddof=1) / np.sqrt(k)) if k > 1 else float("nan")
            row[f"{p}_{m}"] = float(v.mean())
            row[f"{p}_{m}_sem_seeds"] = sem_seed
            row[f"{p}_{m}_std_rls"] = float(np.sqrt(np.mean(s ** 2)))
            row[f"{p}_{m}_se"] = float(np.nanmax([sem_seed, np.sqrt(np.mean(s ** 2))]))
            row[f"{p}_{m}_values"] = v.tolist()
    # how far apart the methods are in one session, against how far apart the sessions are
    d = np.array([r.methods["simultaneous"]["J_4z"].value - r.methods["mixed"]["J_4z"].value for r in results])
    row["J_4z_sim_minus_mixed"] = float(d.mean())
    row["J_4z_sim_minus_mixed_absmax"] = float(np.abs(d).max())
    row["J_4z_mixed_sd_seeds"] = float(np.std(row["J_4z_mixed_values"], ddof=1)) if len(d) > 1 else float("nan")
    row["region"] = classify(row, z)
    return row


def classify(row: dict, z: float = Z) -> str:
    """Region of a point. A method's J_4z is *resolved* when every seed has the sign of the mean and the mean is more
    than ``z`` standard errors from zero, the standard error being the larger of the seed scatter's s.e.m. and the
    mean RLS std of one session: the region says what one session tells (a seed changes the strokes and the noise)."""
    zz = {}
    for m in ("mixed", "simultaneous"):
        v = np.asarray(row[f"J_4z_{m}_values"])
        same_sign = bool(np.all(np.sign(v) == np.sign(v.mean())))
        zz[m] = row[f"J_4z_{m}"] / row[f"J_4z_{m}_se"] if same_sign else 0.0
    zm, zs = zz["mixed"], zz["simultaneous"]
    if abs(zm) < z or abs(zs) < z:
        return "unidentifiable"
    if zm > 0 and zs < 0:
        return "paper"
    if zm > 0 and zs > 0:
        return "agree_positive"
    if zm < 0 and zs < 0:
        return "agree_negative"
    return "opposite"


def full_grid() -> list[Point]:
    """The default map (7 points x 3 seeds, ~15 min of one core): the default arm (1:50 on axis 4) and 1:20 and 1:10
    (J_4z's share of what motor 4 feels ~6x and ~12x larger), friction exactly eq. 1 or departing from it."""
    return [Point(50, 1.0, "eq1"), Point(50, 1.0, "stribeck+load"),
            Point(20, 1.0, "eq1"), Point(20, 1.0, "asym"), Point(20, 1.0, "stribeck+load"),
            Point(20, 1.0, "stribeck+load", "all"), Point(10, 1.0, "eq1")]


def write_outputs(rows: list[dict], out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "map.json").write_text(json.dumps({"z": Z, "points": rows}, indent=1))
    cols = [k for k in rows[0] if not k.endswith("_values") and k != "seeds"]
    with open(out / "map.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items() if k in cols})


def markdown(rows: list[dict]) -> str:
    """The map as the docs show it (J_4z in 1e-4 kg m^2: mean over seeds, each seed, one session's RLS std)."""
    out = ["| axis-4 gear | friction beyond eq. 1 | J_4z share | J_4z truth | J_4z mixed: mean (seeds) ± RLS std | "
           "J_4z simultaneous: mean (seeds) ± RLS std | B_4 mixed / simultaneous (1e-5 N m s/rad, truth 8.0) | "
           "region |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        fr = "none" if r["friction"] == "eq1" else f"{r['friction']} (axis {r['friction_axes']})"
        cells = []
        for m in ("mixed", "simultaneous"):
            seeds = ", ".join(f"{1e4 * v:+.1f}" for v in r[f"J_4z_{m}_values"])
            cells.append(f"{1e4 * r[f'J_4z_{m}']:+.1f} ({seeds}) ± {1e4 * r[f'J_4z_{m}_std_rls']:.1f}")
        out.append(f"| 1:{r['gear4']:g} | {fr} | {r['share']:.2f} | {1e4 * r['J_4z_truth']:.1f} | {cells[0]} | "
                   f"{cells[1]} | {1e5 * r['B_4_mixed']:.1f} / {1e5 * r['B_4_simultaneous']:.1f} | {r['region']} |")
    return "\n".join(out)


def fig3_plot(run: RunResult, title: str):
    """The paper's Fig. 3 for one run: RLS convergence of J_4z, B_4, f_c4 under both methods, truth dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(3, 1, figsize=(7, 6.4), sharex=True)
    for a, p, unit in zip(axs, ("J_4z", "B_4", "fc_4"), ("kg m²", "N m s/rad", "N m")):
        tails = []
        for m, style in (("mixed", "b-"), ("simultaneous", "r-")):
            it, h = run.history[m]
            y = np.asarray(h[p])
            a.plot(it, y, style, lw=1.2, label=f"{m}: {run.methods[m][p].value:.3g} ± {run.methods[m][p].std:.1g}")
            tails.append(y[len(y) // 2:])   # y-range from the converged half (early RLS steps swing wildly)
        a.axhline(run.truth[p], color="k", ls=":", lw=1, label=f"truth (eq. 1 part) {run.truth[p]:.3g}")
        if p == "J_4z":
            a.axhline(0.0, color="0.6", lw=0.6)
        t = np.concatenate(tails + [[run.truth[p]]] + ([[0.0]] if p == "J_4z" else []))
        lo, hi = t.min(), t.max()
        pad = 0.15 * max(hi - lo, 1e-12)
        a.set_ylim(lo - pad, hi + pad)
        a.set_ylabel(f"{p} ({unit})", fontsize=9)
        a.legend(fontsize=7, loc="best")
    axs[-1].set_xlabel("RLS iteration (samples)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return fig


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n", 2)[2])
    p.add_argument("--out", type=Path, default=REPO / "runs" / "fig3_study", help="logs, map.json, map.csv")
    p.add_argument("--figdir", type=Path, help="write fig3_study_<region>.png here")
    p.add_argument("--quick", action="store_true", help="the test's points: one seed, shortened trials")
    p.add_argument("--seeds", type=int, default=3, help="seeds per point (default 3; --quick: 1)")
    p.add_argument("--point", action="append", default=[], metavar="N4:WRIST:FRICTION:AXES:NOISE",
                   help="study only these points, e.g. 20:1:stribeck+load:all:1 (repeatable)")
    return p.parse_args(argv)


def parse_point(text: str) -> Point:
    parts = text.split(":")
    if len(parts) != 5:
        fail(f"--point {text!r}: expected N4:WRIST:FRICTION:AXES:NOISE, e.g. 20:1:stribeck+load:all:1")
    try:
        pt = Point(float(parts[0]), float(parts[1]), parts[2], parts[3], float(parts[4]))
    except ValueError:
        fail(f"--point {text!r}: N4, WRIST and NOISE must be numbers")
    if pt.friction not in FRICTION:
        fail(f"--point {text!r}: unknown friction {pt.friction!r} (known: {', '.join(FRICTION)})")
    if pt.friction_axes not in ("4", "all"):
        fail(f"--point {text!r}: AXES must be 4 or all")
    if pt.gear4 <= 0 or pt.wrist <= 0 or pt.noise < 0:
        fail(f"--point {text!r}: N4 and WRIST must be > 0, NOISE >= 0")
    return pt


def main(argv=None) -> int:
    from js2spec.errors import Js2Error

    try:
        return _main(argv)
    except Js2Error as exc:
        fail(str(exc))


def _main(argv=None) -> int:
    a = parse_args(argv)
    if a.seeds < 1:
        fail(f"--seeds {a.seeds}: need at least one seed")
    points = [parse_point(t) for t in a.point] or (quick_points() if a.quick else full_grid())
    seeds = list(range(1 if a.quick and a.seeds == 3 else a.seeds))
    rows, runs = [], {}
    t0 = time.perf_counter()
    for pt in points:
        res = run_point(pt, seeds, a.out, a.quick)
        row = summarise(res)
        rows.append(row)
        runs[pt.key] = res
        print(f"{pt.key}: share {row['share']:.3f}, J_4z mixed {row['J_4z_mixed']:+.3e} ± {row['J_4z_mixed_se']:.1e}, "
              f"simultaneous {row['J_4z_simultaneous']:+.3e} ± {row['J_4z_simultaneous_se']:.1e} "
              f"(truth {row['J_4z_truth']:.3e}) -> {row['region']}", flush=True)
    write_outputs(rows, a.out)
    print(markdown(rows))
    import resource

    cpu = sum(getattr(resource.getrusage(w), k) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
              for k in ("ru_utime", "ru_stime"))
    print(f"wrote {a.out / 'map.json'} and map.csv ({len(rows)} points, {time.perf_counter() - t0:.0f} s wall, "
          f"{cpu:.0f} s CPU including the js2-acquire sessions this run made)")
    if a.figdir:
        a.figdir.mkdir(parents=True, exist_ok=True)
        import matplotlib.pyplot as plt

        # representative point of a region: the one where J_4z is the largest share of what motor 4 feels (the
        # most favourable to identifying it; the later in the grid on a tie), its first seed
        rep = {}
        for row in rows:
            if row["share"] >= rep.get(row["region"], {"share": -1.0})["share"] - 1e-9:
                rep[row["region"]] = row
        for reg, row in rep.items():
            run = runs[row["key"]][0]
            f = fig3_plot(run, f"Fig. 3, region '{reg}': {row['key']} (seed {run.seed}{', --quick' if a.quick else ''}),"
                               f" J_4z share {row['share']:.2f}")
            path = a.figdir / f"fig3_study_{'quick_' if a.quick else ''}{reg}.png"
            f.savefig(path, dpi=80, bbox_inches="tight")
            plt.close(f)
            print(f"wrote {path}")
    return 0


def quick_points() -> list[Point]:
    return [Point(gear4=50, friction="stribeck+load"), Point(gear4=10, friction="eq1"),
            Point(gear4=20, friction="stribeck+load")]


if __name__ == "__main__":
    raise SystemExit(main())
