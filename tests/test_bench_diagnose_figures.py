"""The README's and docs/diagnosis.md's benchmark figures are what scripts/bench_diagnose.py computes from its
committed rows: docs/bench/diagnose-bench-{all,fresh,hard}-2026-11-24-held.json (cases 0-135 diagnosed with this
release, the model's friction holding the torque at rest), -new- (cases 136-159, drawn after this release's code was
final) and, without -held, the last release's rows of the same recordings. Re-running the cases takes ~15 minutes on
two cores, so the suite pins the figures to the measured rows, exactly."""
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
DOC = (ROOT / "docs" / "diagnosis.md").read_text()


def _scored(which: str) -> tuple[list, dict]:
    """The committed rows of docs/bench/diagnose-bench-WHICH.json and bench_diagnose's score of them."""
    sys.path.insert(0, str(ROOT / "scripts"))
    import bench_diagnose

    rows = json.loads((ROOT / "docs" / "bench" / f"diagnose-bench-{which}.json").read_text())["rows"]
    return rows, bench_diagnose.score(rows)


@pytest.fixture(scope="module")
def scored():
    return _scored("all-2026-11-24")


def test_rates_in_the_readme_are_the_benchmarks(scored):
    rows, s = scored
    assert len(rows) == 72 and [r["seed"] for r in rows] == list(range(72))
    assert (s["effects_found"], s["effects"]) == (54, 83) and "Right effect and joint: **54 of 83 concealed effects (65 %)**" in DOC
    assert round(100 * s["effect_rate"]) == 65
    assert (s["clean_none"], s["clean"]) == (11, 11) and "Clean cases: **11 of 11" in DOC
    assert (s["visible_found"], s["visible"]) == (54, 67) and "**67 effects the residual shows, 54 are named right (81 %)**" in DOC
    assert round(100 * s["visible_rate"]) == 81
    assert len(s["below_floor"]) == 16 and "16 of the 83 remove less than 12 %" in DOC
    fn = {k: v for k, v in s["false_names"].items() if v}
    assert fn == {"stribeck": 4, "payload_change": 2, "torque_offset": 2, "coupling": 1, "asymmetric_friction": 1}
    assert "**False names: 10** (Stribeck 4, payload 2, torque offset 2, coupling 1, asymmetric friction 1)" in DOC
    assert "10 at the last release, 14 before it)" in README


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
    rows, s = _scored("fresh-2026-11-24")
    assert [r["seed"] for r in rows] == list(range(72, 96))
    assert (s["effects_found"], s["effects"]) == (24, 30) and (s["visible_found"], s["visible"]) == (24, 25)
    assert (s["clean_none"], s["clean"]) == (3, 3) and sum(s["false_names"].values()) == 1
    assert "no false name (1 before)" in README
    assert "Right effect and joint: 24 of 30 (80 %)" in DOC and "Visible effects: 24 of 25 (96 %)" in DOC
    kinds = [e["kind"] for r in rows for e in r["effects"]]
    assert kinds.count("thermal_drift") == 10 and kinds.count("coupling") == 13     # the mix the docs state


def test_hard_cases_figures_are_the_benchmarks():
    """Cases 96-135, drawn for the hard kinds after the code was final: the rows where js2 is not ahead."""
    rows, s = _scored("hard-2026-11-24")
    assert [r["seed"] for r in rows] == list(range(96, 136))
    assert (s["effects_found"], s["effects"]) == (21, 46) and (s["visible_found"], s["visible"]) == (20, 34)
    assert (s["clean_none"], s["clean"]) == (3, 4) and "(21 of 46, 3 of 4 and 10 before)" in README
    assert "**Backlash 3 of 12.**" in DOC
    on_clean = sum(v for k, v in s["confusion"]["none"].items() if k != "nothing")
    assert (sum(s["false_names"].values()), on_clean) == (9, 1)                                   # 9 + the clean one
    assert "Right effect and joint: 21 of 46 (46 %). Visible: 20 of 34 (59 %). Clean: 3 of 4 (75 %" in DOC
    conf = s["confusion"]
    assert conf["joint_elasticity"]["joint_elasticity"] == 0 and sum(conf["joint_elasticity"].values()) == 12
    assert conf["backlash"]["backlash"] == 3 and sum(conf["backlash"].values()) == 12
    assert conf["cogging"]["cogging"] == 9 and sum(conf["cogging"].values()) == 12
    fine = [(e["periods_per_rev"], any(f["kind"] == "cogging" and f["joint"] == e["joints"][0] for f in r["named"]))
            for r in rows for e in r["effects"] if e["kind"] == "cogging" and e["periods_per_rev"] >= 12]
    assert (sum(found for _, found in fine), len(fine)) == (5, 8) and "5 of 8 at the last release" in DOC


# --- this release: the model's friction holds the torque at rest (cases 0-135 re-diagnosed) ---------------------------
@pytest.fixture(scope="module")
def held():
    return _scored("all-2026-11-24-held")


def test_held_rates_in_the_readme_are_the_benchmarks(held):
    rows, s = held
    assert [r["seed"] for r in rows] == list(range(72))
    assert (s["effects_found"], s["effects"]) == (56, 83) and "**56 of 83 (67 %, goal 90 %)**" in README
    assert round(100 * s["effect_rate"]) == 67 and "**56 of 83 concealed effects (67 %)**" in DOC
    assert (s["clean_none"], s["clean"]) == (10, 11) and "**10 of 11 clean cases**" in README
    assert (s["visible_found"], s["visible"]) == (56, 67) and "**56 are named right (84 %)**" in README
    assert round(100 * s["visible_rate"]) == 84 and "Visible: **56 of 67 (84 %)**" in DOC
    assert len(s["below_floor"]) == 16 and "16 of the 83 remove less than 12 %" in README
    fn = {k: v for k, v in s["false_names"].items() if v}
    assert fn == {"torque_offset": 3, "payload_change": 2, "joint_elasticity": 2, "coupling": 1}
    on_clean = {k: v for k, v in s["confusion"]["none"].items() if k != "nothing" and v}
    assert on_clean == {"cogging": 1}
    assert ("False names: **9** (torque offset 3,\npayload 2, elasticity 2, coupling 1, and that cogging" in README
            and "**False names: 9** (10 at the last release)" in DOC)
    missed = [m[2] for m in s["visible_missed"]]
    assert len(missed) == 11 and missed.count("joint_elasticity") == 4 and missed.count("backlash") == 5
    assert "The 11 misses there are joint elasticity 4 of 5" in README


def test_held_confusion_rows_and_parameter_errors_in_the_docs_are_the_benchmarks(held):
    import numpy as np

    _, s = held
    cols = ["nothing", "stribeck", "cogging", "payload_change", "thermal_drift", "load_dependent_friction",
            "asymmetric_friction", "joint_elasticity", "backlash", "coupling", "torque_offset"]
    for kind, row in s["confusion"].items():
        cells = " | ".join(str(row[c]) if row[c] else "." for c in cols)
        label = "none (11 clean cases)" if kind == "none" else kind
        assert f"| {label} | {cells} |" in DOC, (kind, cells)
    err = s["param_errors"]
    for kind, key, med_doc, max_doc, n_doc in [("payload_change", "mass", 1.3, 45, 5), ("stribeck", "velocity", 45, 111, 5),
                                               ("cogging", "amplitude", 1.6, 16, 8),
                                               ("thermal_drift", "time_constant", 5.8, 15, 10),
                                               ("coupling", "coefficient", 1.3, 7.2, 8), ("backlash", "width", 17.6, 29, 4),
                                               ("joint_elasticity", "stiffness", 16.5, 16.5, 1)]:
        v = [100 * e[key]["rel_error"] for e in err[kind] if key in e and np.isfinite(e[key]["rel_error"])]
        assert len(v) == n_doc, kind
        for got, doc in ((float(np.median(v)), med_doc), (float(np.max(v)), max_doc)):
            assert got == pytest.approx(doc, abs=0.05 if doc != int(doc) else 0.5), (kind, got, doc)
    assert "| payload | mass | 1.3 % | 45 % | 5" in DOC and "| Stribeck | v_s | 45 % | 111 % | 5" in DOC
    assert "| backlash | width | 17.6 % | 29 % | 4 |" in DOC and "stiffness 16.5 % off" in README


def test_held_fresh_and_hard_figures_are_the_benchmarks():
    rows, s = _scored("fresh-2026-11-24-held")
    assert [r["seed"] for r in rows] == list(range(72, 96))
    assert (s["effects_found"], s["effects"]) == (24, 30) and "**24 of 30 (80 %)**" in README
    assert (s["visible_found"], s["visible"]) == (24, 25) and "**visible 24 of 25 (96 %)**" in README
    assert (s["clean_none"], s["clean"]) == (3, 3) and sum(s["false_names"].values()) == 0
    assert "**24 of 30 (80 %), visible 24 of 25 (96 %)**, clean 3 of 3,\n**no false name**" in DOC
    rows, s = _scored("hard-2026-11-24-held")
    assert [r["seed"] for r in rows] == list(range(96, 136))
    assert (s["effects_found"], s["effects"]) == (20, 46) and "**20 of 46 (43 %)**" in README
    assert (s["visible_found"], s["visible"]) == (20, 34) and "**visible 20 of 34\n(59 %)**" in README
    assert (s["clean_none"], s["clean"]) == (4, 4) and "clean **4 of 4**, 11 false names" in README
    assert sum(s["false_names"].values()) == 11
    conf = s["confusion"]
    assert conf["joint_elasticity"]["joint_elasticity"] == 0 and sum(conf["joint_elasticity"].values()) == 12
    assert conf["backlash"]["backlash"] == 3 and sum(conf["backlash"].values()) == 12
    assert conf["cogging"]["cogging"] == 8 and sum(conf["cogging"].values()) == 12 and "cogging 8 of 12 (9:" in DOC
    assert "elasticity 0 of 12; backlash 3 of 12" in README
    # the 250 Hz shoulders with play or elasticity: 9 of the 11 false names
    on_250_shoulders = sum(1 for r in rows if r["seed"] in (109, 120, 135) for f in r["named"]
                           if (f["kind"], f["joint"]) not in {(e["kind"], e["joints"][0]) for e in r["effects"]})
    assert on_250_shoulders == 9 and "(9 of the 11)" in README
    fine = [(e["periods_per_rev"], any(f["kind"] == "cogging" and f["joint"] == e["joints"][0] for f in r["named"]))
            for r in rows for e in r["effects"] if e["kind"] == "cogging" and e["periods_per_rev"] >= 12]
    assert (sum(found for _, found in fine), len(fine)) == (4, 8) and "benchmark cases 4 of 8 fine ripples" in DOC


def test_no_false_stribeck_since_the_hold_at_rest():
    """Every false Stribeck of the last release (6 in cases 0-135) is gone; the true ones are kept (5 of 5 in 0-71)."""
    def false_stribecks(which):
        rows, _ = _scored(which)
        return sum(1 for r in rows for f in r["named"] if f["kind"] == "stribeck"
                   and ("stribeck", f["joint"]) not in {(e["kind"], e["joints"][0]) for e in r["effects"]})
    assert sum(false_stribecks(f"{w}-2026-11-24") for w in ("all", "fresh", "hard")) == 6
    assert sum(false_stribecks(f"{w}-2026-11-24-held") for w in ("all", "fresh", "hard")) == 0
    assert "none is named in the 136 cases now (6 before)" in README
    _, s = _scored("all-2026-11-24-held")
    assert s["confusion"]["stribeck"]["stribeck"] == 5 and sum(s["confusion"]["stribeck"].values()) == 5


def test_new_cases_figures_are_the_benchmarks():
    """Cases 136-159, drawn and diagnosed once after this release's code was final: its out-of-sample check."""
    rows, s = _scored("new-2026-11-24-held")
    assert [r["seed"] for r in rows] == list(range(136, 160))
    assert (s["effects_found"], s["effects"]) == (8, 27) and "**8 of 27\n(30 %)**" in README
    assert (s["visible_found"], s["visible"]) == (8, 19) and "**visible 8 of 19 (42 %)**" in README
    assert (s["clean_none"], s["clean"]) == (3, 3) and "clean **3 of 3**, 8 false names" in README
    assert sum(s["false_names"].values()) == 8 and "**False names: 8**" in DOC
    assert "**Right effect and joint: 8 of 27 (30 %). Visible: 8 of 19 (42 %). Clean: 3 of 3.**" in DOC
    conf = s["confusion"]
    hard = sum(conf[k][k] for k in ("joint_elasticity", "backlash"))
    assert (hard, sum(conf["joint_elasticity"].values()) + sum(conf["backlash"].values())) == (1, 15)
    cog = [(e["periods_per_rev"], any(f["kind"] == "cogging" and f["joint"] == e["joints"][0] for f in r["named"]))
           for r in rows for e in r["effects"] if e["kind"] == "cogging"]
    assert len(cog) == 6 and all(found == (p <= 4) for p, found in cog)     # the coarse 3 named, the fine 3 not


def test_clean_cases_over_every_set_of_this_release():
    sets = [_scored(f"{w}-2026-11-24-held")[1] for w in ("all", "fresh", "hard", "new")]
    assert (sum(s["clean_none"] for s in sets), sum(s["clean"] for s in sets)) == (20, 21)
    assert "Clean cases over the four sets: **20 of 21 (95 %)** name nothing." in README
