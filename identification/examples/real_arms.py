"""Identify the two real arms in ../shared/data/real and compare with what their authors published.

    python -m identification.examples.real_arms [DATA_DIR] [-o OUTDIR]

* Staubli TX40 (FIGAROH examples): motor encoders + motor torques at 5 kHz, coupled wrist (q_m6 = N6 (q5 + q6)).
  Fit on rows 0-24750, validate on rows 29250-45000 (the maintainers' split). Published: FIGAROH's friction / rotor
  inertia / offset values (TX40_config.yaml) and base parameters (TX40_bp_5_figaroh-plus.csv), joint side.
* KUKA LWR4+ (FloBaRoID): joint torque sensors, 200 Hz. Fit on measurements_1, validate on measurements_3 (another
  trajectory). Published: FloBaRoID's identified URDF, Gaz et al.'s URDF, the CAD URDF (inertials only: their drive
  terms are refitted on the same fitting data), and FloBaRoID's reported CAD+friction residual RMS.

Both run through the product path: js2-import -> js2 log -> identify (simultaneous method: these recordings have no
sequential friction tests) -> validation on the held-out part.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
DEFAULT_DATA = HERE.parents[2] / "shared" / "data" / "real"

# FloBaRoID documentation/analysis_findings.md (via ../shared/notes/identification-anchors.md): CAD URDF + friction
# vs real KUKA data, residual RMS per joint (N m)
FLOBAROID_CAD_FRICTION_RMS = [0.36, 1.55, 0.49, 0.98, 0.63, 0.49, 0.27]


TX40_RATE = 5000.0                  # Hz
# the maintainers' split (FIGAROH): fit rows 0-24750, validation rows 29250-45000
TX40_TRIALS = [("excitation", 0.0, 24750 / TX40_RATE), ("validation", 29250 / TX40_RATE, 45000 / TX40_RATE)]
KUKA_RATE = 200.0                   # Hz


def tx40_paths(data: Path) -> tuple[Path, Path, Path]:
    """(recording folder, URDF, drives.yaml) of the TX40 under ``data``."""
    d = data / "staubli_tx40"
    return d, d / "kinematics" / "tx40_mdh_modified.urdf", HERE / "staubli_tx40" / "drives.yaml"


def load_tx40(data: Path):
    """The TX40 recording as js2-import reads it (:class:`identification.importer.Recording`, motor side)."""
    from identification import importer as im

    d, _, _ = tx40_paths(data)
    return im.load_csvs(d / "data" / "pos_read_data.csv", d / "data" / "curr_data.csv", rate=TX40_RATE)


def write_tx40(rec, data: Path, out: Path, trials=TX40_TRIALS, source_text: str | None = None) -> Path:
    """A TX40 recording (``load_tx40``'s, changed or not) written as js2-import writes it, with ``trials``
    (default: the maintainers' split)."""
    from identification import importer as im

    _, urdf, drives = tx40_paths(data)
    return im.write_log(rec, urdf, drives, out, robot="staubli_tx40", rate=TX40_RATE, source_text=source_text,
                        trials=trials)


def import_tx40(data: Path, out: Path, source_text: str | None = None) -> Path:
    return write_tx40(load_tx40(data), data, out, source_text=source_text)


def kuka_paths(data: Path) -> tuple[Path, Path, Path]:
    """(recording folder, URDF, drives.yaml) of the KUKA LWR4+ under ``data``."""
    d = data / "kuka_lwr4"
    return d, d / "kinematics" / "kuka_lwr4.urdf", HERE / "kuka_lwr4" / "drives.yaml"


def load_kuka(data: Path, which: int):
    """measurements_<which> as js2-import reads it (:class:`identification.importer.Recording`, joint side) and the
    provider's own arrays (``positions``, ``velocities``, ``accelerations``, rad, rad/s, rad/s^2)."""
    from identification import importer as im

    d, _, _ = kuka_paths(data)
    path = d / "data" / f"measurements_{which}.npz"
    with np.load(path) as raw:
        provided = {k: np.asarray(raw[k], float) for k in ("positions", "velocities", "accelerations")}
    return im.load_npz(path), provided


def write_kuka(rec, data: Path, out: Path, decimate: int = 1, trials=None,
               part: tuple[float, float] | None = None) -> Path:
    """A KUKA recording written as js2-import writes it: every ``decimate``-th sample kept (2: 200 Hz -> 100 Hz),
    then, with ``part`` (from, to), only that share of its length (one file of a session recorded in parts)."""
    from identification import importer as im

    if decimate > 1:
        rec.t, rec.position, rec.torque = rec.t[::decimate], rec.position[::decimate], rec.torque[::decimate]
    if part is not None:
        a, b = (int(round(x * len(rec.t))) for x in part)
        rec.t, rec.position, rec.torque = rec.t[a:b], rec.position[a:b], rec.torque[a:b]
    _, urdf, drives = kuka_paths(data)
    return im.write_log(rec, urdf, drives, out, robot="kuka_lwr4", rate=KUKA_RATE / decimate, positions_side="joint",
                        trials=trials)


def import_kuka(data: Path, out_dir: Path) -> list[Path]:
    return [write_kuka(load_kuka(data, i)[0], data, out_dir / f"kuka_{i}.mcap") for i in (1, 2, 3)]


def tx40_published(data: Path, drives) -> dict:
    """FIGAROH's published TX40 drive terms (joint side) mapped onto the motor-side model of eq. 1.

    Axes 1-4 and motor 5 map exactly (B = fv/N^2, f_c = fs/|N|, J_a = Ia/N^2); motor 6 takes the coupling terms
    (fvm6, fsm6, Iam6), which act on q5 + q6 like motor 6 does. FIGAROH's joint-6-only terms (fv6, fs6, Ia6 on q6
    alone) have no counterpart in a per-motor model and are left out; offsets map through K^T."""
    cfg = yaml.safe_load((data / "staubli_tx40" / "published" / "TX40_config.yaml").read_text())
    rp = cfg["identification"]["robot_params"][0]
    N = np.array(rp["reduction_ratio"], float)
    fv, fs, Ia, off = (np.array(rp[k], float) for k in ("fv", "fs", "Ia", "offset"))
    B = fv / N ** 2
    fc = fs / np.abs(N)
    Ja = Ia / N ** 2
    B[5], fc[5], Ja[5] = rp["fvm6"] / N[5] ** 2, rp["fsm6"] / abs(N[5]), rp["Iam6"] / N[5] ** 2
    off_m = drives.gear_ratio_matrix.T @ off
    out = {}
    for k in range(6):
        out.update({f"B_{k + 1}": B[k], f"fc_{k + 1}": fc[k], f"Ja_{k + 1}": Ja[k], f"off_{k + 1}": off_m[k]})
    return {"fixed": out, "N": N, "fv": fv, "fs": fs, "Ia": Ia, "fvm6": rp["fvm6"], "fsm6": rp["fsm6"],
            "Iam6": rp["Iam6"]}


def figaroh_bp(data: Path) -> dict:
    """FIGAROH-plus identified base parameters (OLS column) by name."""
    out = {}
    for line in (data / "staubli_tx40" / "published" / "TX40_bp_5_figaroh-plus.csv").read_text().splitlines():
        parts = line.rsplit(",", 4)
        if len(parts) == 5:
            try:
                out[parts[0].strip()] = float(parts[1])
            except ValueError:
                pass
    return out


def run_tx40(data: Path, work: Path, progress: bool = False) -> dict:
    from identification.pipeline import IdentifyOptions, identify
    from identification.reference import reference_rms
    from identification.signals import FilterSettings

    log = import_tx40(data, work / "tx40.mcap")
    # FIGAROH's model structure (Coulomb + viscous + offset per axis), so that the friction values compare like for
    # like; the plain-command model (which may add a square-root viscous term) is scripts/bench_real_arms.py's
    ident = identify([log], IdentifyOptions(method="simultaneous", fit_trials=("excitation",), offsets=True,
                                            sqrt_viscous=False, filters=FilterSettings(50.0, 7.0),
                                            progress=progress))
    pub = tx40_published(data, ident.logs[0].drives)
    r_pub, _, _ = reference_rms(ident, fixed=pub["fixed"], refit=False)
    r_cad, _, _ = reference_rms(ident, refit=True)
    N = pub["N"]
    bpf = figaroh_bp(data)
    # our motor-side drive terms as joint-side equivalents (axes 1-5 exact; motor 6 <-> FIGAROH's *m6 terms)
    mr = ident.model
    ja, _, alone = ident.motor_inertia()
    # separately identifiable J_a: the unconstrained estimate, like FIGAROH-plus's OLS values (the exported model's
    # J_a comes from the physically consistent fit, which trades them against the link inertias)
    for k in range(6):
        if alone[k]:
            ja[k] = mr.beta[ident.param_index(f"Ja_{k + 1}")]
    off = np.array([mr.beta[ident.param_index(f"off_{k + 1}")] for k in range(6)])
    ours = {"fv": ident.friction_viscous * N ** 2, "fs": ident.friction_coulomb * np.abs(N), "Ia": ja * N ** 2,
            "off_motor": off, "alone": alone}
    pub_fig = {"fv": [bpf.get(f"fv{k}") for k in range(1, 6)] + [bpf.get("fvm6")],
               "fs": [bpf.get(f"fs{k}") for k in range(1, 6)] + [bpf.get("fsm6")],
               "Ia": [None, None] + [bpf.get(f"Ia{k}") for k in range(3, 6)] + [bpf.get("Iam6")]}
    pub_cfg = {"fv": list(pub["fv"][:5]) + [pub["fvm6"]], "fs": list(pub["fs"][:5]) + [pub["fsm6"]],
               "Ia": list(pub["Ia"][:5]) + [pub["Iam6"]]}
    return {"ident": ident, "rms": ident.validation[ident.chosen]["rms"], "nrms": ident.validation[ident.chosen]["nrms"],
            "rms_physical": ident.validation["physical"]["rms"] if "physical" in ident.validation else None,
            "rms_published": r_pub, "rms_cad_refit": r_cad, "ours": ours, "figaroh_bp": pub_fig,
            "figaroh_cfg": pub_cfg, "N": N}


def run_kuka(data: Path, work: Path, progress: bool = False) -> dict:
    from identification.pipeline import IdentifyOptions, identify
    from identification.reference import reference_rms

    logs = import_kuka(data, work)
    ident = identify([logs[0]], IdentifyOptions(method="simultaneous", fit_trials=("excitation",), offsets=True,
                                                sqrt_viscous=False, validate_paths=(str(logs[2]),),
                                                progress=progress))
    pubdir = data / "kuka_lwr4" / "published"
    refs = {}
    for name, path in (("FloBaRoID identified URDF", pubdir / "kuka_lwr4_identified.urdf"),
                       ("Gaz et al. 2016 URDF", pubdir / "kuka_lwr4_gaz.urdf"),
                       ("CAD URDF", data / "kuka_lwr4" / "kinematics" / "kuka_lwr4.urdf")):
        try:
            refs[name] = reference_rms(ident, path.read_text(), refit=True)[0]
        except Exception as exc:  # noqa: BLE001 - a published URDF we cannot evaluate is reported, not fatal
            refs[name] = f"not evaluated: {exc}"
    # FloBaRoID's URDF also publishes its friction (<dynamics damping friction>): evaluated as published too
    from identification.reference import published_friction

    fixed = published_friction((pubdir / "kuka_lwr4_identified.urdf").read_text(), list(ident.arm.joints))
    refs["FloBaRoID identified URDF as published (its damping/friction, offsets refitted)"] = reference_rms(
        ident, (pubdir / "kuka_lwr4_identified.urdf").read_text(), fixed=fixed, refit=True)[0]
    return {"ident": ident, "rms": ident.validation[ident.chosen]["rms"], "nrms": ident.validation[ident.chosen]["nrms"],
            "rms_physical": ident.validation["physical"]["rms"] if "physical" in ident.validation else None,
            "refs": refs, "flobaroid_cad_friction_rms": FLOBAROID_CAD_FRICTION_RMS}


def _f(x, p=3):
    return "—" if x is None or (isinstance(x, float) and not np.isfinite(x)) else f"{x:.{p}g}"


def markdown(tx: dict | None, ku: dict | None) -> str:
    out = []
    if tx is not None:
        out.append("### Stäubli TX40 — validation RMS per motor (N·m, motor side; rows 29250–45000 held out)\n")
        out.append("| motor | ours (simultaneous, base params) | ours (physically consistent) | FIGAROH published "
                   "drive terms + CAD inertials | CAD inertials + drive terms refitted |")
        out.append("|---|---|---|---|---|")
        for k in range(6):
            out.append(f"| {k + 1} | {_f(tx['rms'][k])} | {_f(tx['rms_physical'][k]) if tx['rms_physical'] is not None else '—'} "
                       f"| {_f(tx['rms_published'][k])} | {_f(tx['rms_cad_refit'][k])} |")
        out.append("\n### Stäubli TX40 — drive parameters, joint-side equivalents (fv N·m·s/rad, fs N·m, Ia kg·m²)\n")
        out.append("| axis | fv ours | fv FIGAROH-plus | fv config | fs ours | fs FIGAROH-plus | fs config | Ia ours "
                   "| Ia FIGAROH-plus | Ia config |")
        out.append("|---|---|---|---|---|---|---|---|---|---|")
        for k in range(6):
            lab = f"{k + 1}" if k < 5 else "m6 (q5+q6)"
            ia = _f(tx["ours"]["Ia"][k]) + ("" if tx["ours"]["alone"][k] else "*")
            out.append(f"| {lab} | {_f(tx['ours']['fv'][k])} | {_f(tx['figaroh_bp']['fv'][k])} | "
                       f"{_f(tx['figaroh_cfg']['fv'][k])} | {_f(tx['ours']['fs'][k])} | {_f(tx['figaroh_bp']['fs'][k])} "
                       f"| {_f(tx['figaroh_cfg']['fs'][k])} | {ia} | {_f(tx['figaroh_bp']['Ia'][k])} | "
                       f"{_f(tx['figaroh_cfg']['Ia'][k])} |")
        out.append("\n\\* regrouped with link inertias (value from the physically consistent split)\n")
    if ku is not None:
        out.append("### KUKA LWR4+ — validation RMS per joint (N·m, joint torque sensors; fit measurements_1, "
                   "validate measurements_3)\n")
        names = list(ku["refs"])
        out.append("| joint | ours (simultaneous, base params) | ours (physically consistent) | "
                   + " | ".join(n if "published" in n else f"{n} + drive terms refitted" for n in names)
                   + " | FloBaRoID reported, CAD + friction |")
        out.append("|---" * (4 + len(names)) + "|")
        for k in range(7):
            cells = [_f(ku["refs"][n][k]) if not isinstance(ku["refs"][n], str) else "—" for n in names]
            out.append(f"| {k} | {_f(ku['rms'][k])} | {_f(ku['rms_physical'][k])} | " + " | ".join(cells)
                       + f" | {ku['flobaroid_cad_friction_rms'][k]} |")
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("data", nargs="?", type=Path, default=DEFAULT_DATA)
    p.add_argument("-o", "--outdir", type=Path, default=Path("runs/real_arms"))
    a = p.parse_args(argv)
    if not a.data.is_dir():
        print(f"real_arms: error: {a.data}: data folder not found", flush=True)
        return 2
    a.outdir.mkdir(parents=True, exist_ok=True)
    tx = run_tx40(a.data, a.outdir, progress=True)
    ku = run_kuka(a.data, a.outdir, progress=True)
    from identification import output
    from identification.report import write_report

    for name, res in (("tx40", tx), ("kuka", ku)):
        d = a.outdir / name
        d.mkdir(exist_ok=True)
        output.write_model(res["ident"], d)
        output.write_urdf(res["ident"], d)
        v = output.write_verdict(res["ident"], d)
        write_report(res["ident"], d, v)
    print(markdown(tx, ku))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
