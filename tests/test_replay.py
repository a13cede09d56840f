"""Simulation against the recording (issue 11, item 6): the recorded motion replayed through hil_sim with the
identified model, then with the effects the diagnosis found (js2-diagnose --replay, js2-sim --replay)."""
import json
import re

import numpy as np
import pytest

from fixtures_diag import clean_model, recording

PAYLOAD = [{"kind": "payload_change", "joints": [5], "mass": 0.3, "com": [0.05, 0.0, 0.0]}]


@pytest.fixture(scope="module")
def payload_diag(tmp_path_factory):
    """js2-diagnose --replay on a simulated recording with a concealed payload on the hand."""
    from diagnosis.cli import main

    out = tmp_path_factory.mktemp("replay") / "diag"
    rec = recording(json.dumps(PAYLOAD))
    assert main([str(clean_model()), str(rec), "-o", str(out), "--replay", "-q"]) == 0
    return rec, out, json.loads((out / "diagnosis.json").read_text())


def test_model_replay_is_the_diagnosis_prediction():
    """The identified model as a hil_sim Plant, driven along the recorded motion, needs exactly the torque the
    diagnosis predicts with eq. 1 (same motion, same filter): the replay is the model, not an approximation."""
    from diagnosis.residual import residual_data
    from hil_sim.replay import replay_recording
    from js2spec.log import read_log
    from js2spec.model import load_model

    rec = recording(json.dumps(PAYLOAD))
    rep = replay_recording(rec, clean_model())
    rd = residual_data(load_model(clean_model()), read_log(rec))
    assert np.nanmax(np.abs(rep.tau_model - rd.tau_pred)[rd.mask]) < 1e-9
    assert rep.tau_effects is None


def test_inverse_replay_returns_the_torque_that_drove_the_plant():
    """Forward and inverse agree: the plant (with friction effects, cogging and a payload) is driven by a torque;
    replaying its own motion (states and accelerations from the plant) gives back that torque."""
    from hil_sim.plant import Plant
    from hil_sim.replay import inverse_replay
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    plant = Plant(robot, seed=1, effects=[
        {"kind": "stribeck", "joints": [0], "velocity": 3.0},
        {"kind": "cogging", "joints": [2], "amplitude": 0.004, "periods_per_rev": 3, "phase": 0.4},
        {"kind": "asymmetric_friction", "joints": [1], "negative_scale": 1.4},
        {"kind": "payload_change", "mass": 0.4, "com": [0.03, 0.0, 0.02]}])
    rng = np.random.default_rng(3)
    N = 60
    q = rng.uniform(-0.5, 0.5, (N, 6)) * 50
    dq = rng.choice([-1, 1], (N, 6)) * rng.uniform(2, 30, (N, 6))          # moving: friction has its sign
    tau = rng.normal(0, 0.1, (N, 6))
    ddq = np.array([plant.forward_dynamics(q[s], dq[s], tau[s]) for s in range(N)])
    back = inverse_replay(plant, np.arange(N) * 0.002, q, dq, ddq).tau_motor
    np.testing.assert_allclose(back, tau, atol=1e-9)


def test_inverse_replay_heats_by_friction_power_like_the_plant():
    """thermal_drift with friction_power_heating along a replayed constant speed: the temperature settles where
    the plant's rule puts it, T = p (1 + alpha T) (B w + f_c) w, from the config's friction (not from the current)."""
    from hil_sim.plant import Plant
    from hil_sim.replay import inverse_replay
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    p_heat, alpha, w = 2.0, 0.01, 40.0
    plant = Plant(robot, seed=1, effects=[{"kind": "thermal_drift", "joints": [3], "friction_power_heating": p_heat,
                                           "time_constant": 0.5, "friction_per_kelvin": alpha}])
    t = np.arange(3000) * 0.002
    q = np.zeros((len(t), 6))
    q[:, 3] = w * t
    dq = np.zeros_like(q)
    dq[:, 3] = w
    rep = inverse_replay(plant, t, q, dq, np.zeros_like(q))
    B, fc = plant.friction.viscous[3], plant.friction.coulomb[3]
    power0 = (B * w + fc) * w
    steady = p_heat * power0 / (1 - p_heat * alpha * power0)
    assert rep.temperature_rise[-1, 3] == pytest.approx(steady, rel=1e-3)
    assert rep.temperature_rise[:, [0, 1, 2, 4, 5]].max() == 0.0


def test_forward_replay_of_the_plants_own_torque_retraces_its_motion():
    """The plant driven by a torque, then replayed forward from the same start with that torque: it retraces the
    motion (the tracking term stays ~0); a plant without the payload drifts off and needs tracking."""
    from hil_sim.plant import Plant
    from hil_sim.replay import forward_replay
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    eff = [{"kind": "stribeck", "joints": [0], "velocity": 3.0},
           {"kind": "payload_change", "mass": 0.4, "com": [0.03, 0.0, 0.02]}]
    plant = Plant(robot, seed=1, effects=eff)
    plant.reset()
    dt = 0.002
    t = np.arange(0, 2.0, dt)
    tau = plant.gravity_torque() + 0.1 * np.sin(2 * np.pi * 0.8 * t)[:, None] * np.array([0.3, 1.0, 0.5, 0.1, 0.1, 0.1])
    q, dq = [], []
    for s in range(len(t)):
        q.append(plant.q_motor)
        dq.append(plant.dq_motor)
        plant.step(tau[s], dt)
    q, dq = np.array(q), np.array(dq)
    same = forward_replay(Plant(robot, seed=1, effects=eff), t, q, dq, tau)
    other = forward_replay(Plant(robot, seed=1), t, q, dq, tau)
    assert np.nanmax(np.abs(same.q_motor - q)) < 1e-9 and np.nanmax(np.abs(same.tau_pd)) < 1e-6
    assert np.nanmax(np.abs(other.q_motor - q)) > 1e-3 and np.nanmax(np.abs(other.tau_pd)) > 1e-3


def test_elastic_joint_replay_follows_the_forward_simulation():
    """joint_elasticity: the motors' motion of a forward run of the elastic plant, prescribed; the replay simulates
    the deflection and needs the torque the forward run applied (within 5 % of its RMS; a rigid replay is off by
    more)."""
    from hil_sim.plant import Plant
    from hil_sim.replay import inverse_replay
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    eff = [{"kind": "joint_elasticity", "joints": [1], "stiffness": 1500.0, "damping": 3.0}]
    plant = Plant(robot, seed=1, effects=eff)
    plant.reset()
    dt = 0.002
    t = np.arange(0, 2.0, dt)
    g = plant.gravity_torque()
    tau = g + 0.15 * np.sin(2 * np.pi * 1.3 * t)[:, None] * np.array([0.3, 1.0, 0.5, 0.1, 0.1, 0.1])
    q, dq = [], []
    for s in range(len(t)):
        q.append(plant.q_motor)
        dq.append(plant.dq_motor)
        plant.step(tau[s], dt)
    q, dq = np.array(q), np.array(dq)
    ddq = np.gradient(dq, dt, axis=0)
    moving = np.all(np.abs(dq) > 1.0, axis=1)[:, None] & np.ones((1, 6), bool)
    moving[:50] = False
    el = inverse_replay(Plant(robot, seed=1, effects=eff), t, q, dq, ddq)
    rigid = inverse_replay(Plant(robot, seed=1), t, q, dq, ddq)
    rms = np.sqrt(np.mean(tau[moving[:, 1], 1] ** 2))
    err_el = np.sqrt(np.mean((el.tau_motor - tau)[moving[:, 1], 1] ** 2))
    err_rigid = np.sqrt(np.mean((rigid.tau_motor - tau)[moving[:, 1], 1] ** 2))
    assert moving[:, 1].sum() > 200
    assert err_el < 0.05 * rms, (err_el, rms)
    assert err_el < 0.5 * err_rigid, (err_el, err_rigid)
    assert np.ptp(el.deflection[:, 0]) > 1e-5


def test_payload_gap_shrinks_on_the_report_rows_with_the_found_effects(payload_diag):
    rec, out, d = payload_diag
    rep = d["replay"]
    assert rep["effects"][0]["kind"] == "payload_change"
    before, after = np.array(rep["rms_model"]), np.array(rep["rms_model_effects"])
    # the model alone leaves a gap where the payload's gravity acts (shoulder and elbow: several mN m)
    assert before[1] > 0.005 and before[2] > 0.005
    # the simulator with the diagnosed payload closes most of it on rows the search never saw
    assert np.all(after < before)
    assert after[1] < 0.2 * before[1] and after[2] < 0.2 * before[2]
    assert rep["gain"] > 0.8
    # docs/diagnosis.md ("Replay"): motor 2 17.6 -> 0.145 mN m, motor 3 12.7 -> 0.118 mN m, gain 99.9 % (17.8 ->
    # 0.82 and 12.7 -> 0.45, 97.7 %, while the prediction's inertial torque was filtered twice)
    assert before[1] == pytest.approx(0.0176, rel=0.1) and after[1] == pytest.approx(0.000145, rel=0.3)
    assert before[2] == pytest.approx(0.0127, rel=0.1) and after[2] == pytest.approx(0.000118, rel=0.3)
    assert rep["gain"] == pytest.approx(0.999, abs=0.01)
    assert rep["agreement_with_diagnosis_prediction"] < 1e-9
    assert "report rows" in rep["rows"]
    # forward replay (recorded torque + 5 Hz tracking): the joint angles follow the recording more closely with the
    # payload (docs/diagnosis.md: j3 2.8 -> 0.17 mrad, j5 4.7 -> 0.29 mrad), on every joint, and need less tracking
    fw = rep["forward"]
    p0, p1 = np.array(fw["model"]["position_rms"]), np.array(fw["model_effects"]["position_rms"])
    assert fw["model"]["followed"] == 1.0 and fw["model_effects"]["followed"] == 1.0
    assert np.all(p1 <= p0 * 1.01)
    assert p0[2] == pytest.approx(2.8e-3, rel=0.2) and p1[2] == pytest.approx(0.17e-3, rel=0.4)
    assert p0[4] == pytest.approx(4.7e-3, rel=0.2) and p1[4] == pytest.approx(0.29e-3, rel=0.4)
    t0, t1 = np.array(fw["model"]["tracking_torque_rms"]), np.array(fw["model_effects"]["tracking_torque_rms"])
    assert t1[1] < 0.5 * t0[1] and t1[2] < 0.5 * t0[2]
    html = (out / "report.html").read_text()
    assert "Simulation against the recording" in html
    assert html.count("data:image/png;base64") >= 3


def test_js2_sim_replay_writes_a_simulated_recording(payload_diag, tmp_path, capsys):
    from hil_sim.cli import main
    from js2spec.log import read_log

    rec, out, _ = payload_diag
    sim = tmp_path / "sim.mcap"
    assert main(["--replay", str(rec), "--model", str(clean_model()), "--effects", str(out / "effects.yaml"),
                 "-o", str(sim)]) == 0
    text = capsys.readouterr().out
    assert "forward replay" in text and "followed model 100%, effects 100%" in text
    rows = {m.group(1): (float(m.group(2)), float(m.group(3))) for m in
            re.finditer(r"^\s+(j\d)\s+model ([\d.e-]+) N\*m\s+model \+ effects ([\d.e-]+) N\*m", text, re.M)}
    assert set(rows) == {f"j{i}" for i in range(1, 7)}
    assert rows["j2"][1] < 0.2 * rows["j2"][0] and rows["j3"][1] < 0.2 * rows["j3"][0]
    orig, log = read_log(rec), read_log(sim)
    assert log.source == "hil_sim:replay" and log.trials() == orig.trials()
    assert log.meta["cycle_hz"] == orig.meta["cycle_hz"]
    n = min(len(log.feedback), len(orig.feedback))
    assert n > 0.95 * len(orig.feedback)
    np.testing.assert_allclose(log.feedback.motor_position[:n], orig.feedback.motor_position[:n], atol=1e-6)
    # the simulated torque follows the recorded one (unfiltered, every sample, rests and reversals included, where
    # stiction and the filtered motion differ): within 10 % of its RMS (measured 7 %)
    tr, ts = orig.feedback.torque[:n], log.feedback.torque[:n]
    assert np.sqrt(np.mean((tr - ts) ** 2)) < 0.10 * np.sqrt(np.mean(tr ** 2))
    # --mode forward: the positions the plant reached (with the payload: RMS below 1 mrad at the joints, never 10)
    fwd = tmp_path / "fwd.mcap"
    assert main(["--replay", str(rec), "--model", str(clean_model()), "--effects", str(out / "effects.yaml"),
                 "-o", str(fwd), "--mode", "forward"]) == 0
    lf = read_log(fwd)
    m = min(len(lf.feedback), len(orig.feedback))
    assert m > 0.95 * len(orig.feedback) and lf.meta["source"] == "hil_sim:replay"
    dqj = (lf.feedback.motor_position[:m] - orig.feedback.motor_position[:m]) @ np.asarray(
        orig.drives.gear_ratio_matrix, float).T
    assert np.sqrt(np.mean(dqj ** 2)) < 1e-3 and 0 < np.max(np.abs(dqj)) < 1e-2


def _other_arm(src, dst):
    """The same recording, but of an arm whose joints are named a1..a6."""
    from js2spec.log import LogWriter, read_log

    lg = read_log(src)
    fb = lg.feedback
    rename = lambda s: re.sub(r"\bj([1-6])\b", r"a\1", s)   # noqa: E731
    with LogWriter(dst, robot="other", cycle_hz=lg.cycle_hz, source="test", urdf_text=rename(lg.urdf_text),
                   drives_yaml=rename(lg.drives_yaml)) as w:
        for k in range(0, len(fb), 10):
            w.feedback(int(fb.cycle[k]), float(fb.t[k]), fb.motor_position[k], fb.torque[k], fb.motor_current[k])
    return dst


@pytest.mark.parametrize("case", ["missing_model", "other_arm", "no_model_flag", "bad_effects"])
def test_bad_input_is_one_line_exit_2(case, tmp_path, capsys):
    from hil_sim.cli import main

    rec = recording(json.dumps(PAYLOAD))
    args = {"missing_model": ["--replay", str(rec), "--model", str(tmp_path / "nomodel"),
                              "-o", str(tmp_path / "o.mcap")],
            "other_arm": ["--replay", str(_other_arm(rec, tmp_path / "other.mcap")), "--model", str(clean_model()),
                          "-o", str(tmp_path / "o.mcap")],
            "no_model_flag": ["--replay", str(rec), "-o", str(tmp_path / "o.mcap")],
            "bad_effects": ["--replay", str(rec), "--model", str(clean_model()), "--effects", str(tmp_path / "e.yaml"),
                            "-o", str(tmp_path / "o.mcap")]}[case]
    (tmp_path / "e.yaml").write_text("effects:\n- {kind: cogging, joints: [1], amplitude: 0.01}\n")
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    expect = {"missing_model": "model file not found", "other_arm": "not the model's",
              "no_model_flag": "go together", "bad_effects": "periods_per_rev"}[case]
    assert expect in err[0]
    if case == "bad_effects":
        assert "e.yaml" in err[0]
    assert not (tmp_path / "o.mcap").exists()


def test_stribeck_finding_replays_with_its_fitted_breakaway(tmp_path):
    """A concealed Stribeck on j2 (v_s = 4 rad/s): the finding carries its fitted breakaway level, and the simulator
    with it closes most of motor 2's gap on the report rows (docs/diagnosis.md: 0.77 -> 0.17 mN m); motors it does
    not touch are unchanged."""
    from diagnosis.cli import main

    rec = recording(json.dumps([{"kind": "stribeck", "joints": [1], "velocity": 4.0}]))
    assert main([str(clean_model()), str(rec), "-o", str(tmp_path / "d"), "--replay", "-q"]) == 0
    rep = json.loads((tmp_path / "d" / "diagnosis.json").read_text())["replay"]
    assert rep["effects"][0]["kind"] == "stribeck" and 0.03 < rep["effects"][0]["static"] < 0.045   # truth 0.032
    before, after = np.array(rep["rms_model"]), np.array(rep["rms_model_effects"])
    assert before[1] == pytest.approx(0.77e-3, rel=0.15) and after[1] == pytest.approx(0.172e-3, rel=0.2)
    np.testing.assert_allclose(np.delete(after, 1), np.delete(before, 1), rtol=1e-9)
    assert rep["gain"] == pytest.approx(0.077, abs=0.03)
    fw = rep["forward"]
    p0, p1 = np.array(fw["model"]["position_rms"]), np.array(fw["model_effects"]["position_rms"])
    assert p0[1] == pytest.approx(0.26e-3, rel=0.3) and p1[1] == pytest.approx(0.10e-3, rel=0.4)
    np.testing.assert_allclose(p1[3:], p0[3:], rtol=0.1)        # wrist: not ahead, within 10 % either way


def test_inverse_replay_holds_exactly_where_the_shared_rest_rule_says():
    """inverse_replay with a recorded torque holds friction on the samples js2spec.drives.at_rest marks (the
    diagnosis' rule: motor_rest_speed of a joint-side min_speed), and only there: a standing motor gets the
    recorded torque (within f_s), one creeping below its rest speed moves towards it, and at or above the rest
    speed (the threshold itself included) the hold changes nothing."""
    from hil_sim.plant import Plant
    from hil_sim.replay import inverse_replay
    from js2spec.drives import at_rest, motor_rest_speed
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    plant = Plant(robot, seed=1)
    v_rest = motor_rest_speed(0.01, robot.drives.K)
    rng = np.random.default_rng(7)
    N = 200
    kind = rng.integers(0, 4, (N, 6))            # 0 standing, 1 creeping below v_rest, 2 at v_rest, 3 moving
    scale = np.choose(kind, [np.zeros((N, 6)), rng.uniform(0.2, 0.99, (N, 6)), np.ones((N, 6)),
                             rng.uniform(1.01, 3.0, (N, 6))])
    dq = rng.choice([-1.0, 1.0], (N, 6)) * scale * v_rest
    q = rng.uniform(-20, 20, (N, 6))
    ddq = rng.normal(0, 5, (N, 6))
    t = np.arange(N) * 0.002
    free = inverse_replay(plant, t, q, dq, ddq).tau_motor
    tau_rec = free + rng.uniform(-0.3, 0.3, (N, 6)) * plant.friction.coulomb
    held = inverse_replay(plant, t, q, dq, ddq, tau_recorded=tau_rec, v_rest=v_rest).tau_motor
    rest = at_rest(dq, v_rest)
    np.testing.assert_array_equal(rest, kind <= 1)
    np.testing.assert_allclose(held[kind == 0], tau_rec[kind == 0], rtol=0, atol=1e-12)
    creep = kind == 1
    assert np.all(np.abs(held - tau_rec)[creep] < np.abs(free - tau_rec)[creep])
    np.testing.assert_array_equal(held[~rest], free[~rest])
