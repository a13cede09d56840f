"""Each effect changes torque or motion as its physics says (hil_sim/effects.py has the parameters)."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from hil_sim.plant import Plant
from test_sim_support import Reference, breakaway, constant_speed, js2

POSE = np.array([0.0, 0.3, -0.5, 0.4, 0.6, 0.2])
G = 9.81


def _friction_at_speed(robot, effects, axis, speed, **kw):
    ref = Reference(robot)
    plant = Plant(robot, effects=effects, seed=4)
    return constant_speed(plant, ref, axis, speed, q0=POSE, **kw)[1]


def test_stribeck_raises_low_speed_friction_only():
    robot = js2()
    ref = Reference(robot)
    vs = 5.0
    eff = [{"kind": "stribeck", "joints": [0], "velocity": vs}]
    for speed in (2.0, -3.0):
        plain = _friction_at_speed(robot, None, 0, speed, settle=0.4)
        strib = _friction_at_speed(robot, eff, 0, speed, settle=0.4)
        hump = (ref.fs[0] - ref.fc[0]) * np.exp(-(speed / vs) ** 2)
        assert np.sign(speed) * (strib - plain) == pytest.approx(hump, rel=0.05)
    for speed in (100.0, -100.0):
        plain = _friction_at_speed(robot, None, 0, speed)
        strib = _friction_at_speed(robot, eff, 0, speed)
        assert abs(strib - plain) < 0.005 * ref.fc[0]
    # other joints untouched
    assert _friction_at_speed(robot, eff, 1, 3.0) == pytest.approx(_friction_at_speed(robot, None, 1, 3.0), abs=1e-9)


def test_cogging_is_periodic_in_motor_angle():
    """Static test (eq. 4) at several motor angles on the gravity-free axis 1: the balancing torque is minus the
    cogging torque A sin(p theta + phi); the breakaway friction (eq. 3) is unchanged."""
    robot = js2()
    ref = Reference(robot)
    A, p, phi = 0.004, 6.0, 0.3
    plant = Plant(robot, effects=[{"kind": "cogging", "joints": [0], "amplitude": A, "periods_per_rev": p,
                                   "phase": phi}])
    K00 = ref.K[0, 0]
    for theta in (0.1, 0.1 + np.pi / (2 * p), 0.1 + np.pi / p, 0.1 + 2 * np.pi / p, 0.1 + 2 * np.pi / p * 7):
        q = POSE.copy()
        q[0] = K00 * theta
        hold = ref.gravity_motor(q)
        taus = []
        for d in (+1, -1):
            plant.reset(q)
            taus.append(breakaway(plant, 0, hold, d, rate=0.02, start=0.0))
        balance = (taus[0] + taus[1]) / 2
        assert balance == pytest.approx(-A * np.sin(p * theta + phi), abs=0.02 * A)
        assert (taus[0] - taus[1]) / 2 == pytest.approx(ref.fs[0], rel=0.02)


def test_payload_change_changes_gravity_by_m_g_r():
    robot = js2()
    ref = Reference(robot)
    m, com = 0.3, np.array([0.05, 0.0, 0.0])
    plant = Plant(robot, effects=[{"kind": "payload_change", "mass": m, "com": com.tolist()}])
    nominal = Plant(robot)
    zero = np.zeros(6)
    d_tau = plant.gravity_torque(zero) - nominal.gravity_torque(zero)
    # zero pose: arm along +x; payload at x = 0.30 + 0.12 + 0.13 + 0.06 + 0.05 from joint 2's axis (URDF)
    x_payload = 0.66
    d_joint = np.array([0.0, -m * G * x_payload, -m * G * (x_payload - 0.30), 0.0, -m * G * (x_payload - 0.55), 0.0])
    np.testing.assert_allclose(d_tau, ref.K.T @ d_joint, atol=1e-12)
    # and the static test (eq. 4) on the plant sees it: balancing torque of axis 2 shifts by K22 * (-m g r)
    ref_payload = Reference(robot, payload=(5, m, com))
    hold = ref_payload.gravity_motor(zero)
    taus = []
    for d in (+1, -1):
        plant.reset(zero)
        taus.append(breakaway(plant, 1, hold, d, start=hold[1] + 0.005))
    balance = (taus[0] + taus[1]) / 2
    nominal_gravity = ref.gravity_motor(zero)[1]
    assert balance - nominal_gravity == pytest.approx(ref.K[1, 1] * (-m * G * x_payload), rel=0.02)


def test_thermal_drift_grows_friction_as_the_motor_heats():
    robot = js2()
    ref = Reference(robot)
    heating, tau_th, alpha = 40.0, 1.0, 0.01
    plant = Plant(robot, seed=3, effects=[{"kind": "thermal_drift", "joints": [0], "heating": heating,
                                           "time_constant": tau_th, "friction_per_kelvin": alpha}])
    record = []
    constant_speed(plant, ref, 0, 60.0, q0=POSE, settle=0.3, measure=3.7, record=record, ramp=0.2)
    t = np.array([r[0] for r in record])
    tau_cmd = np.array([r[2][0] for r in record])
    measured = np.array([r[1].tau_motor[0] for r in record])
    # independent first-order model driven by the commanded current
    kt = robot.drives.torque_constant[0]
    rise = np.zeros(len(t))
    x = 0.0
    for k in range(len(t)):
        target = heating * (tau_cmd[k] / kt) ** 2
        x = target + (x - target) * np.exp(-0.002 / tau_th)
        rise[k] = x
    assert plant.temperature_rise[0] == pytest.approx(rise[-1], rel=1e-9)
    assert plant.temperature_rise[1:].max() == 0.0
    assert rise[-1] > 5.0                                   # it really heated
    early = (t > 0.3) & (t < 0.6)
    late = t > 3.5
    ratio = measured[late].mean() / measured[early].mean()
    # friction of the previous step scales the torque: use the rise one sample earlier
    expected = (1 + alpha * np.r_[0, rise[:-1]][late]).mean() / (1 + alpha * np.r_[0, rise[:-1]][early]).mean()
    assert ratio > 1.05
    assert ratio == pytest.approx(expected, rel=0.01)


def test_thermal_drift_heated_by_friction_power():
    """friction_power_heating: the temperature follows |f w| (the gear warming), not the current. At a constant
    speed with no copper-loss heating the steady rise is friction_power_heating * (B w + f_c) w, independently
    computed from the reference friction (the thermal scale on B, f_c included at the rise one step earlier)."""
    robot = js2()
    ref = Reference(robot)
    p_heat, tau_th, alpha, speed = 2.0, 0.5, 0.01, 60.0
    plant = Plant(robot, seed=3, effects=[{"kind": "thermal_drift", "joints": [0], "friction_power_heating": p_heat,
                                           "time_constant": tau_th, "friction_per_kelvin": alpha}])
    constant_speed(plant, ref, 0, speed, q0=POSE, settle=0.3, measure=4.7, ramp=0.2)
    w = plant.dq_motor[0]
    assert w == pytest.approx(speed, rel=0.02)
    # the fixed point of T = p_heat (1 + alpha T) (B w + f_c) w
    power0 = (ref.B[0] * w + ref.fc[0]) * w
    steady = p_heat * power0 / (1 - p_heat * alpha * power0)
    assert steady > 2.0                                       # it really heated
    assert plant.temperature_rise[0] == pytest.approx(steady, rel=0.03)
    assert plant.temperature_rise[1:].max() == 0.0
    # copper losses alone (heating = 0 here) would not have warmed it
    cold = Plant(robot, seed=3, effects=[{"kind": "thermal_drift", "joints": [0], "heating": 0.0,
                                          "time_constant": tau_th, "friction_per_kelvin": alpha}])
    constant_speed(cold, ref, 0, speed, q0=POSE, settle=0.3, measure=1.0, ramp=0.2)
    assert cold.temperature_rise[0] == 0.0


def test_load_dependent_friction_grows_with_load():
    robot = js2()
    ref = Reference(robot)
    mu = 0.1
    plant = Plant(robot, effects=[{"kind": "load_dependent_friction", "joints": [1], "coefficient": mu}])
    results = []
    for pose in (POSE, np.array([0.0, -1.45, 0.0, 0.0, 0.0, 0.0])):
        hold = ref.gravity_motor(pose)
        taus = []
        for d in (+1, -1):
            plant.reset(pose)
            taus.append(breakaway(plant, 1, hold, d, start=hold[1]))
        results.append(((taus[0] - taus[1]) / 2, abs(hold[1])))
    (fs_loaded, load_a), (fs_light, load_b) = results
    assert load_a > 5 * load_b
    assert fs_loaded == pytest.approx(ref.fs[1] + mu * load_a, rel=0.02)
    assert fs_light == pytest.approx(ref.fs[1] + mu * load_b, rel=0.02)


def test_asymmetric_friction_differs_by_direction():
    robot = js2()
    ref = Reference(robot)
    scale = 1.6
    plant = Plant(robot, effects=[{"kind": "asymmetric_friction", "joints": [0], "negative_scale": scale}])
    hold = ref.gravity_motor(POSE)
    plant.reset(POSE)
    tau_plus = breakaway(plant, 0, hold, +1, start=0.0)
    plant.reset(POSE)
    tau_minus = breakaway(plant, 0, hold, -1, start=0.0)
    assert tau_plus == pytest.approx(ref.fs[0], rel=0.02)
    assert -tau_minus == pytest.approx(scale * ref.fs[0], rel=0.02)
    # sliding: Coulomb differs by direction too (eq. 5 intercepts)
    f_pos = _friction_at_speed(robot, [{"kind": "asymmetric_friction", "joints": [0], "negative_scale": scale}], 0, 50.0)
    f_neg = _friction_at_speed(robot, [{"kind": "asymmetric_friction", "joints": [0], "negative_scale": scale}], 0, -50.0)
    assert f_pos == pytest.approx(ref.B[0] * 50 + ref.fc[0], rel=0.02)
    assert f_neg == pytest.approx(-ref.B[0] * 50 - scale * ref.fc[0], rel=0.02)


def _gravity_joint(ref, q_joint):
    return pin.computeGeneralizedGravity(ref.model, ref.data, np.asarray(q_joint, dtype=float))


def test_joint_elasticity_link_and_motor_differ_by_tau_over_k():
    robot = js2()
    ref = Reference(robot)
    k, d = 2000.0, 20.0
    plant = Plant(robot, effects=[{"kind": "joint_elasticity", "joints": [1], "stiffness": k, "damping": d}])
    plant.reset(POSE)
    gear = ref.q_joint(plant.q_motor)
    # reset: static equilibrium, link at POSE
    np.testing.assert_allclose(plant.q_joint, POSE, atol=1e-12)
    assert plant.q_joint[1] - gear[1] == pytest.approx(-_gravity_joint(ref, POSE)[1] / k, rel=1e-9)
    # dynamics: release the spring (no deflection) and let the link sag onto it; motors held at gravity torque
    plant.set_state(plant.q_motor, np.zeros(6), delta=[0.0])
    hold = ref.gravity_motor(POSE)
    for _ in range(500):
        plant.step(hold, 0.002)
    q_link = plant.q_joint
    deflection = q_link - ref.q_joint(plant.q_motor)
    expected = -_gravity_joint(ref, q_link)[1] / k
    assert abs(expected) > 5e-5
    assert deflection[1] == pytest.approx(expected, rel=0.01)
    np.testing.assert_allclose(np.delete(deflection, 1), 0.0, atol=1e-12)     # rigid joints stay rigid
    # the motor sees the spring torque: gear side balance K^T (-k delta) = tau_m (motor 2 stuck, holds it)
    assert abs(plant.dq_joint).max() < 1e-4


def test_backlash_gives_a_dead_zone_on_reversal():
    """From one flank, the gear travels the full play ``b`` before it pushes the link back (joint 1, no gravity)."""
    robot = js2()
    ref = Reference(robot)
    b = 0.01
    travel = {}
    for name, effects, delta0 in (("backlash", [{"kind": "backlash", "joints": [0], "width": b,
                                                 "stiffness": 2000.0, "damping": 10.0}], -b / 2),
                                  ("elastic", [{"kind": "joint_elasticity", "joints": [0], "stiffness": 2000.0,
                                                "damping": 10.0}], 0.0)):
        plant = Plant(robot, effects=effects)
        plant.reset(POSE)
        plant.set_state(plant.q_motor, np.zeros(6), delta=[delta0])
        link0, gear0 = plant.q_joint[0], ref.q_joint(plant.q_motor)[0]
        tau = ref.gravity_motor(POSE)
        tau[0] = -(ref.fs[0] + 0.01)
        for _ in range(2000):
            plant.step(tau, 0.0005)
            if abs(plant.q_joint[0] - link0) > 1e-6:
                break
        else:
            raise AssertionError("link never moved")
        travel[name] = gear0 - ref.q_joint(plant.q_motor)[0]
    assert travel["backlash"] == pytest.approx(b, rel=0.05)
    assert travel["elastic"] < 0.02 * b


def test_torque_offset_is_a_constant_load_the_drive_carries():
    """torque_offset: the same drive torque drives the arm as if it were `offset` smaller; what the drive feels at
    constant speed is the plain arm's torque plus the offset, in both directions."""
    robot = js2()
    off = 0.04
    eff = [{"kind": "torque_offset", "joints": [0], "offset": off}]
    a = Plant(robot, effects=eff, seed=4)
    b = Plant(robot, seed=4)
    a.reset(POSE)
    b.reset(POSE)
    tau = np.array([0.6, 0.2, -0.1, 0.05, 0.02, 0.01])
    for _ in range(200):
        a.step(tau, 0.002)
        b.step(tau - np.array([off, 0, 0, 0, 0, 0]), 0.002)
    np.testing.assert_allclose(a.read_sensors().motor_position, b.read_sensors().motor_position, atol=1e-12)
    assert np.any(a.read_sensors().motor_position != 0)
    for speed in (3.0, -3.0):
        plain = _friction_at_speed(robot, None, 0, speed)
        shifted = _friction_at_speed(robot, eff, 0, speed)
        assert shifted - plain == pytest.approx(off, rel=0.02)
