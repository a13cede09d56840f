"""One effect schema (js2spec.effects) for the simulator and the diagnosis (issue 11, item 4)."""
import numpy as np
import pytest
import yaml

from js2spec.effects import EFFECT_KINDS, markdown_table, parse_effects
from js2spec.errors import ConfigError


def test_hil_sim_parses_with_the_schema():
    import hil_sim.effects as he

    assert he.parse_effects is parse_effects and he.EFFECT_KINDS is EFFECT_KINDS
    assert set(he.EFFECT_PARAMS) == set(EFFECT_KINDS)
    for kind, spec in EFFECT_KINDS.items():
        assert list(he.EFFECT_PARAMS[kind]) == [p.name for p in spec.params]
    # a range of the schema is what the simulator refuses
    assert EFFECT_KINDS["stribeck"].param("velocity").check == "pos"
    with pytest.raises(ConfigError, match=r"effects\[0\]\.velocity.*> 0"):
        parse_effects([{"kind": "stribeck", "joints": [0], "velocity": 0.0}], 6, "x.yaml")


def test_every_schema_parameter_has_a_unit_and_a_known_check():
    from js2spec.effects import CHECKS

    for k in EFFECT_KINDS.values():
        assert k.physics
        for p in k.params:
            assert p.unit and p.check in CHECKS and p.description, (k.name, p.name)
    table = markdown_table()
    for k in EFFECT_KINDS:
        assert f"``{k}``" in table


@pytest.fixture(scope="module")
def clean_rd():
    from diagnosis.residual import residual_data
    from fixtures_diag import clean_model, recording
    from js2spec.log import read_log
    from js2spec.model import load_model

    return residual_data(load_model(clean_model()), read_log(recording("[]")))


def test_every_kind_the_diagnosis_can_name_parses_in_hil_sim(clean_rd):
    """Each named term of the diagnosis' library turns its coefficients into an effect that the simulator's
    parser (the schema's) accepts, with exactly the schema's parameter names, and a Plant builds with it."""
    from diagnosis.library import KINDS, LIBRARY
    from hil_sim.plant import Plant
    from js2spec.robot import load_robot

    assert set(KINDS) <= set(EFFECT_KINDS), set(KINDS) - set(EFFECT_KINDS)
    rd = clean_rd
    robot = load_robot("js2")
    for term in LIBRARY:
        if term.reference:
            continue
        j = 1
        grid = term.grid(rd, j)
        if not grid:                    # tries nothing on joint 1 (a far coupling whose source is j's neighbour)
            continue
        h = grid[len(grid) // 2]
        k = term.columns(rd, j, h).shape[2]
        eff, summary, _ok, _why = term.effect(rd, j, h, np.full(k, 0.05), np.full(k, 0.001))
        assert eff["kind"] == term.kind
        names = set(eff) - {"kind", "joints"}
        assert names <= set(EFFECT_KINDS[term.kind].param_names), (term.kind, names)
        missing = {p.name for p in EFFECT_KINDS[term.kind].params if p.required} - names
        assert not missing, (term.kind, missing)
        parsed = parse_effects([eff], rd.n, "diagnosis", joints=rd.joints)
        Plant(robot, effects=parsed)


def test_written_effects_yaml_carries_the_schema_units_and_parses(tmp_path, clean_rd):
    from types import SimpleNamespace

    from diagnosis.report import effects_yaml

    fake = SimpleNamespace(rd=clean_rd, sim_effects=lambda: [
        {"kind": "payload_change", "joints": [5], "mass": 0.3, "com": [0.05, 0.0, 0.0]},
        {"kind": "cogging", "joints": [2], "amplitude": 0.004, "periods_per_rev": 2, "phase": 0.1}])
    path = tmp_path / "effects.yaml"
    path.write_text(effects_yaml(fake, path))
    text = path.read_text()
    assert "periods_per_rev (1/rev, motor side)" in text and "com (m, link frame)" in text
    items = yaml.safe_load(text)["effects"]
    assert list(items[0]) == ["kind", "joints", "mass", "com", "inertia"]     # the schema's order
    parsed = parse_effects(items, 6, path)
    assert parsed[1]["periods_per_rev"] == 2.0 and parsed[0]["com"].tolist() == [0.05, 0.0, 0.0]
    bad = SimpleNamespace(rd=clean_rd, sim_effects=lambda: [{"kind": "cogging", "joints": [2], "amplitude": -1.0,
                                                             "periods_per_rev": 2}])
    with pytest.raises(ConfigError, match=r"effects\.yaml.*amplitude.*>= 0"):
        effects_yaml(bad, path)


def test_stribeck_static_is_the_breakaway_level_in_the_simulator():
    """The schema's optional ``static`` of a Stribeck effect sets that joint's f_s (the hump's top); without it the
    truth's f_s stays."""
    from hil_sim.plant import Plant
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    base = Plant(robot, effects=[{"kind": "stribeck", "joints": [0], "velocity": 2.0}])
    with_fs = Plant(robot, effects=[{"kind": "stribeck", "joints": [0], "velocity": 2.0, "static": 0.08}])
    assert with_fs.friction.static[0] == 0.08 and base.friction.static[0] != 0.08
    assert with_fs.friction.static[1] == base.friction.static[1]
    slow = np.zeros(6)
    slow[0] = 1e-3
    f_slow = with_fs.friction.sliding_at(slow)[0]
    assert f_slow == pytest.approx(0.08 + with_fs.friction.viscous[0] * 1e-3, rel=1e-3)


def test_a_stribeck_finding_simulates_with_its_fitted_breakaway_level():
    """diagnosis' effects carry the fitted hump as ``static`` = the model's f_c + the fitted f_s - f_c, so a model
    without f_s (the simultaneous method) replays the Stribeck it was diagnosed with."""
    from types import SimpleNamespace

    from diagnosis.run import DiagnosisResult

    model = SimpleNamespace(friction_coulomb=np.array([0.02, 0.03]))
    fake = SimpleNamespace(model=model, rd=SimpleNamespace(torque_side="motor", K=np.eye(2)), findings=lambda: [
        {"effect": {"kind": "stribeck", "joints": [1], "velocity": 3.0, "shape": 2.0}, "coefficients": [0.012]},
        {"effect": {"kind": "asymmetric_friction", "joints": [0], "negative_scale": 1.3}, "coefficients": [0.0, 0.1]}])
    eff = DiagnosisResult.sim_effects(fake)
    assert eff[0]["static"] == pytest.approx(0.042) and "static" not in eff[1]
    parsed = parse_effects(eff, 2, "diagnosis")
    assert parsed[0]["static"] == pytest.approx(0.042)
