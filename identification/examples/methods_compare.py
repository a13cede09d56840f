"""Mixed vs simultaneous method: the paper's Fig. 2 and Fig. 3 and the J_4z / B_4 comparison, from logs.

    # 1. two simulator sessions through js2-acquire (in-process simulator): nominal, and with axis-4 friction that
    #    eq. 1 does not have (Stribeck hump + load-dependent Coulomb friction), via a copy of configs/js2 whose
    #    sim_truth.yaml switches those effects on
    python -m identification.examples.methods_compare --generate runs/methods_compare
    # 2. compare (optionally against a truth file of the simulator, for the reader's information only)
    python -m identification.examples.methods_compare runs/methods_compare/session_nominal.mcap \
        --truth configs/js2/sim_truth.yaml --figdir docs/img

The identification package does not import the simulator or the acquisition code: sessions are made by running the
``js2-acquire`` command, and the truth file, when given, is only printed beside the estimates.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

EFFECTS_AXIS4 = [{"kind": "stribeck", "joints": [3], "velocity": 15.0},
                 {"kind": "load_dependent_friction", "joints": [3], "coefficient": 0.15}]
PARAMS = ("J_4z", "B_4", "fc_4", "Ja_4")
CONFIGS = Path(__file__).resolve().parents[2] / "configs" / "js2"


def generate(outdir: Path, configs: Path = CONFIGS) -> list[Path]:
    """Run js2-acquire twice (nominal and axis-4 friction effects); returns the two log paths."""
    outdir.mkdir(parents=True, exist_ok=True)
    paths = []
    for key, effects in (("nominal", []), ("axis4", EFFECTS_AXIS4)):
        folder = Path(tempfile.mkdtemp(prefix=f"js2_{key}_")) / "js2"
        shutil.copytree(configs, folder)
        truth = yaml.safe_load((folder / "sim_truth.yaml").read_text())
        truth["effects"] = effects
        (folder / "sim_truth.yaml").write_text(yaml.safe_dump(truth, sort_keys=False))
        out = outdir / f"session_{key}.mcap"
        cmd = [sys.executable, "-m", "js2io.cli", "--robot", str(folder), "--trial",
               "static,velocity,acceleration,validation", "--seed", "0", "-o", str(out), "--no-progress"]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise SystemExit(f"methods_compare: js2-acquire failed: {r.stderr.strip()}")
        paths.append(out)
        shutil.rmtree(folder.parent, ignore_errors=True)
    return paths


def truth_beta(ident, truth_path: Path) -> np.ndarray:
    """Base parameters of (URDF inertials + the truth file's drive terms), for printing beside the estimates."""
    from identification.regressor import standard_vector

    t = yaml.safe_load(Path(truth_path).read_text())
    pi = standard_vector(ident.arm, motor_inertia=t["motor_inertia"], viscous=t["viscous"], coulomb=t["coulomb"])
    return ident.bp.beta(pi), pi


def compare(path: Path, truth: Path | None = None) -> dict:
    from identification.pipeline import IdentifyOptions, identify, predict_standard, rms_nrms

    ident = identify([path], IdentifyOptions(method="mixed"))
    bt, pi = truth_beta(ident, truth) if truth else (None, None)
    rows = []
    for name in PARAMS:
        i = ident.param_index(name)
        row = {"param": name, "base": ident.bp.names[i], "truth": None if bt is None else bt[i]}
        for m in ("mixed", "simultaneous"):
            row[m], row[m + "_std"] = ident.methods[m].beta[i], ident.methods[m].std[i]
        rows.append(row)
    res = {"ident": ident, "rows": rows, "rms": {m: ident.validation[m]["rms"] for m in ("mixed", "simultaneous")}}
    if pi is not None:
        pred, meas = predict_standard(ident, pi)
        res["rms_truth"] = rms_nrms(pred, meas)[0]
    return res


def table(res: dict, title: str) -> str:
    lines = [f"#### {title}\n", "| parameter | truth | mixed | simultaneous |", "|---|---|---|---|"]
    for r in res["rows"]:
        tr = "—" if r["truth"] is None else f"{r['truth']:.4g}"
        lines.append(f"| {r['param']} (`{r['base'][:60]}`) | {tr} | {r['mixed']:.4g} ± {r['mixed_std']:.1g} | "
                     f"{r['simultaneous']:.4g} ± {r['simultaneous_std']:.1g} |")
    n = len(res["rms"]["mixed"])
    lines += ["", "| validation RMS (N·m) | " + " | ".join(f"axis {k + 1}" for k in range(n)) + " |",
              "|---" * (n + 1) + "|"]
    for m in ("mixed", "simultaneous"):
        lines.append(f"| {m} | " + " | ".join(f"{x:.3g}" for x in res["rms"][m]) + " |")
    if "rms_truth" in res:
        lines.append("| truth's drive terms, same filters | " + " | ".join(f"{x:.3g}" for x in res["rms_truth"]) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("logs", nargs="*", type=Path, help="session logs to compare (one table each)")
    p.add_argument("--generate", type=Path, metavar="OUTDIR", help="make the two simulator sessions first")
    p.add_argument("--truth", type=Path, help="simulator truth file to print beside the estimates")
    p.add_argument("--figdir", type=Path, help="write fig2_<log>.png and fig3_<log>.png here")
    a = p.parse_args(argv)
    logs = list(a.logs)
    if a.generate:
        logs += generate(a.generate)
    if not logs:
        p.error("give logs or --generate OUTDIR")
    from identification.report import _plt, fig2, fig3

    for log in logs:
        res = compare(log, a.truth)
        print(table(res, log.name))
        print()
        if a.figdir:
            a.figdir.mkdir(parents=True, exist_ok=True)
            plt = _plt()
            for tag, f in (("fig2", fig2(res["ident"])), ("fig3", fig3(res["ident"]))):
                if f is not None:
                    f.savefig(a.figdir / f"{tag}_{log.stem}.png", dpi=80, bbox_inches="tight")
                    plt.close(f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
