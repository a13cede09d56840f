"""scripts/bench_real_arms.py: js2's exported model beats the built-in textbook fit on held-out data on every arm,
and the README's "Real arms" table is exactly what the script prints (each figure within the tolerance the README
states: 1 % of its value). Skipped when ../shared/data/real is absent."""
from __future__ import annotations

import importlib.util
import re

import pytest

from fixtures_id_sim import REAL, REPO

pytestmark = pytest.mark.skipif(not (REAL / "staubli_tx40").is_dir() or not (REAL / "kuka_lwr4").is_dir(),
                                reason=f"real-arm recordings not found at {REAL} (CI has ../shared/data/real)")
README_TOL = 0.01          # the README: "pinned ... to 1 % of each figure"
#: the simulated Js-2 rows: "pinned to 20 % of each figure" (two machines print the textbook fit's joint 4 as 17.63
#: and 20.53 with the same code: the closed-loop simulation with stiction carries the BLAS kernels' rounding)
README_TOL_SIMULATED = 0.20


def _bench_module():
    spec = importlib.util.spec_from_file_location("bench_real_arms", REPO / "scripts" / "bench_real_arms.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    return _bench_module().run(REAL, tmp_path_factory.mktemp("bench"))


def _readme_rows() -> list[list[str]]:
    text = (REPO / "README.md").read_text()
    sec = text.split("### Real arms", 1)[1].split("\n### ", 1)[0]
    rows = []
    for line in sec.splitlines():
        if line.startswith("|") and "---" not in line and not line.startswith("| arm |"):
            rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows


def test_js2_beats_the_textbook_fit_on_held_out_data_on_every_arm(results):
    assert [r["arm"].split(" (")[0] for r in results] == ["Stäubli TX40", "KUKA LWR4+", "Js-2"]
    for res in results:
        js2 = next(r for r in res["rows"] if r["model"].startswith("js2"))
        ols = next(r for r in res["rows"] if r["model"].startswith("textbook OLS"))
        assert js2["overall"] < ols["overall"], res["arm"]
    # the real arms: at least 10 % better (the team's goal is 20 %)
    for res in results[:2]:
        js2, ols = res["rows"][0], res["rows"][1]
        assert js2["overall"] < 0.9 * ols["overall"], res["arm"]


def test_readme_table_is_the_bench_output(results):
    rows = _readme_rows()
    printed = []
    for res in results:
        for r in res["rows"]:
            printed.append((r["model"], r["joints"] + [r["overall"]]))
    assert len(rows) == len(printed), "README rows != bench rows"
    arms = [res["arm"] for res in results for _ in res["rows"]]
    for cells, (model, values), arm in zip(rows, printed, arms):
        assert re.sub(r"\*", "", cells[1]) == model
        nums = [float(c) for c in cells[2:-1] if c]
        tol = README_TOL_SIMULATED if arm.startswith("Js-2") else README_TOL
        assert nums == pytest.approx(values, rel=tol, abs=0.005), model
    text = " ".join((REPO / "README.md").read_text().split())
    assert "The simulated Js-2 rows are pinned to 20 % of each figure, not 1 %" in text
