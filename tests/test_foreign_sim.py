"""Tests of the independent TX40 simulator (foreign_sim): physics and recording format."""
import json

import numpy as np
import pinocchio as pin
import pytest
import yaml

from foreign_sim.arm import DRIVES, NJ, TrueArm
from foreign_sim.cases import draw_case
from foreign_sim.plant import Plant, spring_torque
from foreign_sim.record import ENC_Q, record_case, simulate

Q0 = np.array([0.3, 0.5, -0.4, 0.5, 0.6, 0.2])


@pytest.fixture(scope="module")
def arm():
    return TrueArm(0)


def _run_free(plant, seconds, dt):
    E0 = plant.energy()
    Es = []
    for _ in range(int(round(seconds / dt))):
        plant.step(np.zeros(NJ), dt)
        Es.append(plant.energy())
    return E0, np.array(Es)


def test_energy_conserved_rigid(arm):
    p = Plant(arm, [], friction=False)
    p.set_rest(Q0)
    p.zd[:NJ] = np.array([20.0, -15.0, 25.0, 30.0, -20.0, 40.0])   # motor speeds, rad/s
    E0, Es = _run_free(p, 1.0, 1 / 2000)
    assert np.max(np.abs(Es - E0)) < 0.01 * abs(E0)
    assert np.ptp(p.link_state()[0]) > 0     # it did move


def test_energy_conserved_elastic(arm):
    eff = [{"kind": "joint_elasticity", "joints": [1], "stiffness": 2000.0, "damping": 0.0}]
    p = Plant(arm, eff, friction=False)
    p.set_rest(Q0)
    p.zd[:NJ] = 10.0
    E0, Es = _run_free(p, 1.0, 1 / 10000)
    assert np.max(np.abs(Es - E0)) < 0.01 * abs(E0)


def test_karnopp_stiction(arm):
    for frac, moves in ((0.9, False), (1.1, True)):
        p = Plant(arm, [], gravity=False)
        p.set_rest(Q0)
        th0 = p.z[:NJ].copy()
        tau = np.zeros(NJ)
        tau[0] = frac * arm.fs[0]
        for _ in range(1000):
            p.step(tau, 1 / 2000)
        moved = abs(p.z[0] - th0[0]) > 1e-6
        assert moved == moves
        np.testing.assert_allclose(p.z[1:NJ], th0[1:], atol=1e-12)   # the other axes stay stuck


def test_backlash_dead_zone(arm):
    b = 0.01
    defl = np.linspace(-0.99 * b / 2, 0.99 * b / 2, 11)
    np.testing.assert_array_equal(spring_torque(defl, np.ones_like(defl), 1e4, 5.0, b / 2), 0.0)
    out = spring_torque(np.array([b / 2 + 1e-3]), np.array([0.0]), 1e4, 0.0, b / 2)
    np.testing.assert_allclose(out, [10.0])
    # in the plant: a motor turning inside the play does not move the link
    eff = [{"kind": "backlash", "joints": [0], "width": b, "stiffness": 5e4, "damping": 10.0}]
    p = Plant(arm, eff, friction=False, gravity=False)
    p.set_rest(Q0)
    p.zd[0] = 0.5 * (b / 2) / abs(arm.K[0, 0]) / 0.1 * 0.8   # crosses 40 % of the half play in 0.1 s
    for _ in range(1000):
        p.step(np.zeros(NJ), 1 / 10000)
    d = p.KE @ p.z[:NJ] + p.offset[p.E] - p.z[NJ:]
    assert 0 < abs(d[0]) < b / 2
    assert p.z[NJ] == pytest.approx(Q0[0], abs=1e-12) and p.zd[NJ] == 0.0


def test_payload_gravity(arm):
    m, com = 2.0, np.array([0.03, -0.05, 0.04])
    eff = [{"kind": "payload_change", "joints": [4], "mass": m, "com": com.tolist(), "inertia": [0, 0, 0]}]
    p = Plant(arm, eff, friction=False)
    g_true = pin.computeGeneralizedGravity(arm.model, arm.model.createData(), Q0)
    d = arm.model.createData()
    pin.computeJointJacobians(arm.model, d, Q0)
    J = pin.getJointJacobian(arm.model, d, 5, pin.LOCAL_WORLD_ALIGNED)   # joint 5 (0-based 4), world axes
    r = d.oMi[5].rotation @ com                                          # joint origin -> payload, world
    Jp = J[:3] - pin.skew(r) @ J[3:]                                     # the payload point's Jacobian
    dg = -Jp.T @ (m * np.array([0, 0, -9.81]))                           # torque holding its weight
    g_pay = pin.computeGeneralizedGravity(p.model, p.data, Q0)
    np.testing.assert_allclose(g_pay - g_true, dg, atol=1e-9)
    assert np.abs(dg[1]) > 0.1
    p.set_rest(Q0)          # holding torque K^T g_pay gives no acceleration; without the payload's part it falls
    a, _ = p.accelerations(arm.K.T @ g_pay)
    np.testing.assert_allclose(a, 0.0, atol=1e-8)
    a, _ = p.accelerations(arm.K.T @ g_true)
    assert np.max(np.abs(a)) > 1.0


def _short(seed, dur=2.0, **kw):
    c = draw_case(seed)
    c["duration_s"] = dur
    c.update(kw)
    return c


def test_same_seed_identical(tmp_path):
    c = _short(1)
    record_case(c, tmp_path / "a", progress=False)
    record_case(draw_case(1) | {"duration_s": 2.0}, tmp_path / "b", progress=False)
    a, b = np.load(tmp_path / "a/recording.npz"), np.load(tmp_path / "b/recording.npz")
    for k in ("times", "positions", "torques"):
        np.testing.assert_array_equal(a[k], b[k])
    assert draw_case(1) == draw_case(1) and draw_case(1) != draw_case(2)


def test_recording_format(tmp_path, arm):
    c = _short(26, 3.0)
    case = c | {"arm_seed": 0}
    sim = simulate(case, arm, progress=False)
    p = record_case(c, tmp_path, progress=False)
    z = np.load(p)
    assert set(z.files) == {"times", "positions", "torques"}
    N = int(round(3.0 * c["rate_hz"]))
    assert z["times"].shape == (N,) and z["positions"].shape == (N, 6) and z["torques"].shape == (N, 6)
    np.testing.assert_allclose(np.diff(z["times"]), 1.0 / c["rate_hz"])
    dr = yaml.safe_load((tmp_path / "drives.yaml").read_text())
    assert dr == yaml.safe_load(DRIVES.read_text())
    K, off = np.asarray(dr["gear_ratio_matrix"]), np.asarray(dr["joint_offset"])
    # motor-side encoder angles: q_joint = K q_motor + offset (clean case: K_true = K)
    q = z["positions"] @ K.T + off
    np.testing.assert_allclose(q, sim["q"], atol=2 * ENC_Q * np.abs(K).sum(1).max())
    assert np.max(np.abs(z["positions"] / ENC_Q - np.round(z["positions"] / ENC_Q))) < 1e-6
    # units: motor-side N*m, on the scale of the nominal gravity torque through K (not joint side, not mN*m)
    g = np.array([arm.K.T @ pin.computeGeneralizedGravity(arm.nom_model, arm.nom_data, qq) for qq in q[::50]])
    rms_t, rms_g = np.sqrt(np.mean(z["torques"][:, 1] ** 2)), np.sqrt(np.mean(g[:, 1] ** 2))
    assert 0.5 < rms_t / rms_g < 2.0
    # saturation: commanded torque never beyond it; read-back only by the noise
    assert np.all(np.abs(sim["tau_cmd"]) <= arm.tau_sat + 1e-12)
    rms = np.sqrt(np.mean(sim["tau_cmd"] ** 2, 0))
    assert np.all(np.abs(z["torques"]) <= arm.tau_sat + 6 * 0.005 * rms + 1e-4)
    t = json.loads((tmp_path / "truth.json").read_text())
    assert t["arm_seed"] == 0 and t["case"]["seed"] == 26 and t["effects"] == []


def test_saturation_with_tight_limit(arm):
    a2 = TrueArm(0)
    a2.tau_sat = a2.tau_sat * 0.2
    sim = simulate(_short(3, 1.0) | {"arm_seed": 0}, a2, progress=False)
    assert np.all(np.abs(sim["tau_cmd"]) <= a2.tau_sat + 1e-12)
    assert np.any(np.isclose(np.abs(sim["tau_cmd"]), a2.tau_sat))


def test_effect_case_visibility(tmp_path):
    c = draw_case(26)          # starts with multi-sines: joint 1 moves
    c["duration_s"] = 3.0
    c["effects"] = [{"kind": "torque_offset", "joints": [1], "offset": 0.2}]
    record_case(c, tmp_path, progress=False)
    t = json.loads((tmp_path / "truth.json").read_text())
    v = t["visibility"][0]
    # the offset shows while the axis slides (a stuck axis holds it by static friction)
    assert v["kind"] == "torque_offset" and 0.1 < v["effect_rms"] <= 0.2 + 1e-9
    assert 0 < v["ratio"] < 10


@pytest.mark.parametrize("kind", ["joint_elasticity", "backlash"])
def test_elastic_rest_is_static_equilibrium(arm, kind):
    eff = [{"kind": kind, "joints": [1], "stiffness": 5000.0, "damping": 5.0}]
    if kind == "backlash":
        eff[0]["width"] = 0.006
    p = Plant(arm, eff, friction=False)
    p.set_rest(Q0)
    q, _ = p.link_state()
    np.testing.assert_allclose(q, Q0, atol=1e-12)
    g = pin.computeGeneralizedGravity(p.model, p.data, Q0)
    a, _ = p.accelerations(arm.K.T @ g)
    np.testing.assert_allclose(a, 0.0, atol=1e-7)
    d = p.KE @ p.z[:NJ] + p.offset[p.E] - p.z[NJ:]       # deflection = load / k (+ half the play)
    np.testing.assert_allclose(d, g[1] / 5000.0 + (np.sign(g[1]) * 0.003 if kind == "backlash" else 0.0))


def test_cases_valid_effects():
    from js2spec.effects import parse_effects
    kinds = set()
    n_eff = []
    for s in range(40):
        c = draw_case(s)
        json.dumps(c)
        parse_effects(c["effects"], 6)
        assert c["rate_hz"] in (100, 200, 250, 500, 1000) and 30 <= c["duration_s"] <= 60
        js = [e["joints"][0] for e in c["effects"]]
        assert len(set(js)) == len(js)
        kinds |= {e["kind"] for e in c["effects"]}
        n_eff.append(len(c["effects"]))
    assert len(kinds) >= 8 and 0 in n_eff and 2 in n_eff


def test_asymmetric_friction_scales_the_coulomb_level_backwards_not_the_viscous(arm):
    """js2spec's asymmetric_friction: f_c, f_s (and the hump) multiplied by negative_scale in the negative direction;
    B is not (the first version scaled the whole backward friction)."""
    plant = Plant(arm, [{"kind": "asymmetric_friction", "joints": [1], "negative_scale": 0.5}])
    w = np.full(NJ, 2.0)
    fc, fs, B = plant._friction_levels(w)
    forward = plant._sliding(w, fc, fs, B, np.ones(NJ))
    backward = plant._sliding(-w, fc, fs, B, -np.ones(NJ))
    assert forward[1] == pytest.approx(B[1] * 2.0 + fc[1])
    assert backward[1] == pytest.approx(-B[1] * 2.0 - 0.5 * fc[1])
    assert backward[0] == pytest.approx(-forward[0])            # other motors symmetric
