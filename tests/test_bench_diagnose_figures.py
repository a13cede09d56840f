"""The README's and docs/diagnosis.md's benchmark figures are what scripts/bench_diagnose.py computes from its
committed rows (docs/bench/diagnose-bench-all-2026-11-24.json: 72 cases diagnosed with this release). Re-running the
72 cases takes ~15 minutes on two cores, so the suite pins the figures to the measured rows, exactly."""
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
DOC = (ROOT / "docs" / "diagnosis.md").read_text()


def _scored(which: str) -> tuple[list, dict]:
    """The committed rows of docs/bench/diagnose-bench-WHICH-2026-11-24.json and bench_diagnose's score of them."""
    sys.path.insert(0, str(ROOT / "scripts"))
    import bench_diagnose

    rows = json.loads((ROOT / "docs" / "bench" / f"diagnose-bench-{which}-2026-11-24.json").read_text())["rows"]
    return rows, bench_diagnose.score(rows)


@pytest.fixture(scope="module")
def scored():
    return _scored("all")


def test_rates_in_the_readme_are_the_benchmarks(scored):
    rows, s = scored
    assert len(rows) == 72 and [r["seed"] for r in rows] == list(range(72))
    assert (s["effects_found"], s["effects"]) == (54, 83) and "**54 of 83 (65 %, goal 90 %)**" in README
    assert round(100 * s["effect_rate"]) == 65
    assert (s["clean_none"], s["clean"]) == (11, 11) and "**11 of 11 clean cases**" in README
    assert (s["visible_found"], s["visible"]) == (54, 67) and "**54 are named right (81 %)**" in README
    assert round(100 * s["visible_rate"]) == 81
    assert len(s["below_floor"]) == 16 and "16 of the 83 remove less than 12 %" in README
    fn = {k: v for k, v in s["false_names"].items() if v}
    assert fn == {"stribeck": 4, "payload_change": 2, "torque_offset": 2, "coupling": 1, "asymmetric_friction": 1}
    assert "False names: **10** (Stribeck 4, payload 2, torque offset 2, coupling 1, asymmetric friction 1" in README


def test_confusion_rows_in_the_docs_are_the_benchmarks(scored):
    _, s = scored
    conf = s["confusion"]
    cols = ["nothing", "stribeck", "cogging", "payload_change", "thermal_drift", "load_dependent_friction",
            "asymmetric_friction", "joint_elasticity", "backlash", "coupling", "torque_offset"]
    for kind, row in conf.items():
        cells = " | ".join(str(row[c]) if row[c] else "." for c in cols)
        label = "none (11 clean cases)" if kind == "none" else kind
        assert f"| {label} | {cells} |" in DOC, (kind, cells)
    assert conf["backlash"]["backlash"] == 5 and conf["joint_elasticity"]["joint_elasticity"] == 0
    # the visible misses the docs list: elasticity 0 of 5, backlash 4
    missed = [m[2] for m in s["visible_missed"]]
    assert missed.count("joint_elasticity") == 5 and missed.count("backlash") == 4 and len(missed) == 13


def test_parameter_errors_in_the_docs_are_the_benchmarks(scored):
    import numpy as np

    _, s = scored
    err = s["param_errors"]

    def med_max(kind, key):
        v = [100 * e[key]["rel_error"] for e in err[kind] if key in e and np.isfinite(e[key]["rel_error"])]
        return float(np.median(v)), float(np.max(v)), len(v)

    for kind, key, row in [("payload_change", "mass", "| payload | mass | 1.8 % | 48 % | 5"),
                           ("backlash", "width", "| backlash | width | 23 % | 26 % | 5"),
                           ("coupling", "coefficient", "| coupling | coefficient | 1.0 % | 6.1 % | 8 |"),
                           ("thermal_drift", "time_constant", "| thermal drift | time constant | 4.4 % | 26 % | 10 |")]:
        med, mx, n = med_max(kind, key)
        parts = [p.strip() for p in row.split("|")[3:6]]
        assert med == pytest.approx(float(parts[0].rstrip(" %")), abs=0.05 if "." in parts[0] else 0.5), (kind, med)
        assert mx == pytest.approx(float(parts[1].rstrip(" %")), abs=0.05 if "." in parts[1] else 0.5), (kind, mx)
        assert n == int(parts[2].split()[0]) and row in DOC


def test_fresh_cases_figures_are_the_benchmarks():
    """Cases 72-95, drawn after the code was final (an out-of-sample check of the changes made on cases 0-71)."""
    rows, s = _scored("fresh")
    assert [r["seed"] for r in rows] == list(range(72, 96))
    assert (s["effects_found"], s["effects"]) == (24, 30) and "**24 of 30 (80 %)**" in README
    assert (s["visible_found"], s["visible"]) == (24, 25) and "**visible 24 of 25 (96 %)**" in README
    assert (s["clean_none"], s["clean"]) == (3, 3) and sum(s["false_names"].values()) == 1
    assert "Right effect and joint: 24 of 30 (80 %)" in DOC and "Visible effects: 24 of 25 (96 %)" in DOC
    kinds = [e["kind"] for r in rows for e in r["effects"]]
    assert kinds.count("thermal_drift") == 10 and kinds.count("coupling") == 13     # the mix the docs state


def test_hard_cases_figures_are_the_benchmarks():
    """Cases 96-135, drawn for the hard kinds after the code was final: the rows where js2 is not ahead."""
    rows, s = _scored("hard")
    assert [r["seed"] for r in rows] == list(range(96, 136))
    assert (s["effects_found"], s["effects"]) == (21, 46) and "**21 of 46 (46 %)**" in README
    assert (s["visible_found"], s["visible"]) == (20, 34) and "**visible 20 of 34 (59 %)**" in README
    assert (s["clean_none"], s["clean"]) == (3, 4) and "clean **3 of 4**" in README
    assert "backlash 3 of 12" in README and "**Backlash 3 of 12.**" in DOC and "elasticity 0 of 12" in README
    on_clean = sum(v for k, v in s["confusion"]["none"].items() if k != "nothing")
    assert (sum(s["false_names"].values()), on_clean) == (9, 1) and "10 false names" in README   # 9 + the clean one
    assert "Right effect and joint: 21 of 46 (46 %). Visible: 20 of 34 (59 %). Clean: 3 of 4 (75 %" in DOC
    conf = s["confusion"]
    assert conf["joint_elasticity"]["joint_elasticity"] == 0 and sum(conf["joint_elasticity"].values()) == 12
    assert conf["backlash"]["backlash"] == 3 and sum(conf["backlash"].values()) == 12
    assert conf["cogging"]["cogging"] == 9 and sum(conf["cogging"].values()) == 12
    fine = [(e["periods_per_rev"], any(f["kind"] == "cogging" and f["joint"] == e["joints"][0] for f in r["named"]))
            for r in rows for e in r["effects"] if e["kind"] == "cogging" and e["periods_per_rev"] >= 12]
    assert (sum(found for _, found in fine), len(fine)) == (5, 8) and "fine coggings 5 of 8" in README
