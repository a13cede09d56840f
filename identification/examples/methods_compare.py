"""Mixed vs simultaneous method on simulator sessions: the paper's Fig. 2 and Fig. 3 and the J_4z / B_4 story.

    python -m identification.examples.methods_compare [-o OUTDIR]

Generates two sessions with the real trial code (js2io trials on hil_sim.direct.DirectDriveGroup): the nominal
simulator (friction exactly eq. 1's Coulomb + viscous) and one whose axis-4 friction is what real drives have and
eq. 1 has not (Stribeck hump at low speed + load-dependent Coulomb friction). Identifies both with both methods and
prints, with the truth beside them, J_4z (the base parameter holding link 4's inertia about its axis), B_4, f_c4 and
the motor inertia J_a4; writes Fig. 2 and Fig. 3 as PNG.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

EFFECTS_AXIS4 = ({"kind": "stribeck", "joints": [3], "velocity": 15.0},
                 {"kind": "load_dependent_friction", "joints": [3], "coefficient": 0.15})


def make_session(path: Path, effects=()) -> Path:
    from hil_sim.direct import DirectDriveGroup
    from hil_sim.plant import Plant
    from js2io.session import run_trials
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    plant = Plant(robot, seed=0, effects=[dict(e) for e in effects]) if effects else None
    with DirectDriveGroup(robot, plant=plant, seed=0) as g:
        run_trials(g, robot, ["static", "velocity", "acceleration", "validation"], path)
    return path


def compare(path: Path) -> dict:
    from hil_sim.truth import load_truth
    from identification.pipeline import IdentifyOptions, identify, predict_standard, rms_nrms
    from identification.regressor import standard_vector
    from js2spec.robot import load_robot

    ident = identify([path], IdentifyOptions(method="mixed"))
    tr = load_truth(load_robot("js2"))
    pi = standard_vector(ident.arm, motor_inertia=tr.motor_inertia, viscous=tr.viscous, coulomb=tr.coulomb)
    beta_true = ident.bp.beta(pi)
    out = {"ident": ident, "rows": []}
    for name in ("J_4z", "B_4", "fc_4", "Ja_4"):
        i = ident.param_index(name)
        row = {"param": name, "base": ident.bp.names[i], "truth": beta_true[i]}
        for m in ("mixed", "simultaneous"):
            row[m] = ident.methods[m].beta[i]
            row[m + "_std"] = ident.methods[m].std[i]
        out["rows"].append(row)
    pred, meas = predict_standard(ident, pi)
    out["rms_truth"] = rms_nrms(pred, meas)[0]
    out["rms"] = {m: ident.validation[m]["rms"] for m in ("mixed", "simultaneous")}
    return out


def table(res: dict, title: str) -> str:
    lines = [f"#### {title}\n", "| parameter | truth | mixed | simultaneous |", "|---|---|---|---|"]
    for r in res["rows"]:
        lines.append(f"| {r['param']} (`{r['base'][:60]}`) | {r['truth']:.4g} | {r['mixed']:.4g} ± "
                     f"{r['mixed_std']:.1g} | {r['simultaneous']:.4g} ± {r['simultaneous_std']:.1g} |")
    lines.append("")
    lines.append("| validation RMS (N·m) axis 1..6 | " + " | ".join(f"{k + 1}" for k in range(6)) + " |")
    lines.append("|---" * 7 + "|")
    for m in ("mixed", "simultaneous"):
        lines.append(f"| {m} | " + " | ".join(f"{x:.3g}" for x in res["rms"][m]) + " |")
    lines.append("| true parameters, same filters | " + " | ".join(f"{x:.3g}" for x in res["rms_truth"]) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-o", "--outdir", type=Path, default=Path("runs/methods_compare"))
    p.add_argument("--figdir", type=Path, default=None, help="also write fig2/fig3 PNGs here")
    a = p.parse_args(argv)
    a.outdir.mkdir(parents=True, exist_ok=True)
    from identification.report import _plt, fig2, fig3

    results = {}
    for key, eff, title in (("nominal", (), "nominal simulator (friction = eq. 1)"),
                            ("axis4", EFFECTS_AXIS4, "axis-4 friction beyond eq. 1 (Stribeck + load-dependent)")):
        path = make_session(a.outdir / f"session_{key}.mcap", eff)
        res = compare(path)
        results[key] = res
        print(table(res, title))
        print()
        if a.figdir is not None:
            a.figdir.mkdir(parents=True, exist_ok=True)
            plt = _plt()
            f = fig2(res["ident"])
            f.savefig(a.figdir / f"fig2_{key}.png", dpi=80, bbox_inches="tight")
            plt.close(f)
            f = fig3(res["ident"])
            f.savefig(a.figdir / f"fig3_{key}.png", dpi=80, bbox_inches="tight")
            plt.close(f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
