"""The plant's physics against independent computations: eq. 1 torque balance, energy, sensors, determinism."""
from __future__ import annotations

import numpy as np
import pytest

from hil_sim.plant import Plant, SensorReading
from hil_sim.truth import load_truth
from test_sim_support import K_TX40, Reference, js2, make_robot

RNG = np.random.default_rng(12345)


def _random_states(n, count, rng):
    for _ in range(count):
        q_joint = rng.uniform(-1.5, 1.5, n)
        dq_motor = rng.uniform(-150, 150, n)
        tau = rng.uniform(-0.3, 0.3, n)
        yield q_joint, dq_motor, tau


@pytest.mark.parametrize("variant", ["js2", "js2_unequal_wrist_inertia", "tx40_coupling"])
def test_torque_balance_matches_rnea_plus_motor_terms(tmp_path, variant):
    """Forward dynamics (the plant's acceleration) put back into RNEA + eq. 1's motor terms gives the torque."""
    if variant == "js2":
        robot = js2()
    elif variant == "js2_unequal_wrist_inertia":   # reflected inertia not diagonal -> general path
        robot = make_robot(tmp_path, truth_changes={"motor_inertia": [3e-5, 3e-5, 1.6e-5, 8e-6, 6e-6, 9e-6]})
    else:
        robot = make_robot(tmp_path, K=K_TX40)
    plant = Plant(robot)
    assert plant.dyn.fast == (variant == "js2")
    ref = Reference(robot)
    K = ref.K
    worst = 0.0
    for q_joint, dq_motor, tau in _random_states(plant.n, 20, RNG):
        q_motor = np.linalg.solve(K, q_joint - ref.offset)
        ddq_motor = plant.forward_dynamics(q_motor, dq_motor, tau)
        tau_back = ref.motor_torque(q_motor, dq_motor, ddq_motor)
        worst = max(worst, np.max(np.abs(tau_back - tau)))
    assert worst < 1e-9, worst


@pytest.mark.parametrize("coupling", ["js2", "tx40"])
def test_integrated_motion_satisfies_eq1(tmp_path, coupling):
    """Over a real step the finite-difference acceleration satisfies eq. 1 (to the integrator's accuracy)."""
    robot = js2() if coupling == "js2" else make_robot(tmp_path, K=K_TX40)
    plant = Plant(robot)
    ref = Reference(robot)
    rng = np.random.default_rng(3)
    q_motor = np.linalg.solve(ref.K, rng.uniform(-1, 1, plant.n))
    dq_motor = rng.uniform(50, 100, plant.n) * rng.choice([-1, 1], plant.n)
    tau = rng.uniform(-0.2, 0.2, plant.n)
    plant.set_state(q_motor, dq_motor)
    h = 1e-5
    plant.step(tau, h)
    v1 = plant.dq_motor
    plant.set_state(q_motor, dq_motor)
    plant.step(tau, 2 * h)
    v2 = plant.dq_motor
    a0 = (4 * v1 - 3 * dq_motor - v2) / (2 * h)      # one-sided 2nd-order derivative at t = 0
    tau_back = ref.motor_torque(q_motor, dq_motor, a0)
    assert np.max(np.abs(tau_back - tau)) < 1e-6 * np.max(np.abs(tau))


def test_inverse_dynamics_is_eq1_without_friction(tmp_path):
    robot = make_robot(tmp_path, K=K_TX40)
    plant = Plant(robot)
    ref = Reference(robot)
    rng = np.random.default_rng(5)
    for _ in range(5):
        q, dq, ddq = rng.normal(size=(3, plant.n)) * [[3], [80], [500]]
        np.testing.assert_allclose(plant.inverse_dynamics(q, dq, ddq), ref.motor_torque(q, dq, ddq, friction=False),
                                   rtol=0, atol=1e-12)


@pytest.mark.parametrize("coupling", ["js2", "tx40"])
def test_energy_conserved_without_friction(tmp_path, coupling):
    """Friction off, zero torque: links + rotors kinetic + gravity potential constant over 10 s (1e-4 relative).

    Relative to the largest kinetic energy reached (the energy actually exchanged), a stricter measure than
    relative to the total, whose zero is arbitrary."""
    robot = js2() if coupling == "js2" else make_robot(tmp_path, K=K_TX40)
    plant = Plant(robot, truth=load_truth(robot).without_friction())
    ref = Reference(robot)
    plant.reset(np.array([0.3, 0.2, -0.4, 0.5, 0.8, -0.2]))
    e0 = sum(ref.energy(plant.q_motor, plant.dq_motor))
    worst, ke_max = 0.0, 0.0
    for k in range(5000):
        plant.step(np.zeros(plant.n), 0.002)
        if k % 10 == 9:
            ke, pe = ref.energy(plant.q_motor, plant.dq_motor)
            worst = max(worst, abs(ke + pe - e0))
            ke_max = max(ke_max, ke)
    assert plant.t == pytest.approx(10.0)
    assert ke_max > 5.0                       # the arm really swung (J)
    assert worst / ke_max < 1e-4, (worst, ke_max)
    # the plant's own energy bookkeeping agrees with the reference
    assert plant.energy() == pytest.approx(sum(ref.energy(plant.q_motor, plant.dq_motor)), abs=1e-9)


def test_energy_dissipated_with_friction():
    robot = js2()
    plant = Plant(robot)
    ref = Reference(robot)
    plant.reset()
    e_prev = sum(ref.energy(plant.q_motor, plant.dq_motor))
    for _ in range(200):
        plant.step(np.zeros(plant.n), 0.002)
        e = sum(ref.energy(plant.q_motor, plant.dq_motor))
        assert e <= e_prev + 1e-9
        e_prev = e


def test_reset_step_and_state_api():
    robot = js2()
    plant = Plant(robot, seed=1)
    q0 = np.array([0.1, -0.2, 0.3, -0.4, 0.5, -0.6])
    plant.reset(q0)
    np.testing.assert_allclose(plant.q_joint, q0, atol=1e-15)
    np.testing.assert_allclose(robot.drives.joint_from_motor(plant.q_motor), q0, atol=1e-12)
    assert plant.t == 0.0 and not plant.dq_motor.any() and not plant.dq_joint.any()
    g = plant.gravity_torque()
    for _ in range(50):
        plant.step(g, 0.002)              # exactly gravity-compensated: stiction holds, nothing moves
    np.testing.assert_allclose(plant.q_joint, q0, atol=1e-15)
    assert plant.stuck.all()
    assert plant.t == pytest.approx(0.1)
    plant.step(np.zeros(6), 0.0)
    assert plant.t == pytest.approx(0.1)
    with pytest.raises(ValueError):
        plant.step(np.zeros(6), -1.0)


def test_sensors_quantised_noisy_and_deterministic():
    robot = js2()
    drives = robot.drives
    truth = load_truth(robot)
    tau = np.array([0.01, -0.02, 0.005, 0.002, -0.003, 0.004])

    def run(seed):
        plant = Plant(robot, seed=seed)
        plant.reset(np.array([0.0, 0.0, 0.0, 0.0, 0.3, -0.2]))
        out = []
        for _ in range(400):
            plant.step(tau, 0.002)
            out.append(plant.read_sensors())
        return out

    a, b, c = run(7), run(7), run(8)
    r = a[-1]
    assert isinstance(r, SensorReading)
    assert r.encoder_counts.dtype == np.int64
    cpr = drives.encoder_counts_per_rev
    np.testing.assert_allclose(r.motor_position, r.encoder_counts * 2 * np.pi / cpr)
    lsb = drives.rated_current / 1000
    cur = np.array([x.motor_current for x in a])
    np.testing.assert_allclose(cur / lsb, np.round(cur / lsb), atol=1e-9)       # per-mille quantisation
    np.testing.assert_allclose(np.array([x.tau_motor for x in a]), cur * drives.torque_constant)
    # noise: mean is the true current, spread is the configured std (quantisation adds lsb^2/12)
    true_current = tau / drives.torque_constant
    assert np.all(np.abs(cur.mean(axis=0) - true_current) < 4 * truth.current_noise_std / np.sqrt(400) + lsb / 2)
    expected_std = np.sqrt(truth.current_noise_std ** 2 + lsb ** 2 / 12)
    np.testing.assert_allclose(cur.std(axis=0), expected_std, rtol=0.15)
    # determinism under a seed; another seed gives other noise but the same physics
    assert all(np.array_equal(x.motor_current, y.motor_current) and np.array_equal(x.encoder_counts,
               y.encoder_counts) for x, y in zip(a, b))
    assert not all(np.array_equal(x.motor_current, y.motor_current) for x, y in zip(a, c))
    assert all(np.array_equal(x.encoder_counts, y.encoder_counts) for x, y in zip(a, c))
    # encoder is the motor angle rounded to one count
    plant = Plant(robot, seed=7)
    plant.reset(np.array([0.0, 0.0, 0.0, 0.0, 0.3, -0.2]))
    exact = plant.q_motor
    np.testing.assert_array_equal(plant.read_sensors().encoder_counts, np.rint(exact * cpr / (2 * np.pi)))


def test_step_splitting_is_exact_and_substeps_are_fixed():
    """step(tau, 4 ms) == two step(tau, 2 ms) (same fixed 1 ms steps, bit for bit); a finer configured step
    changes the trajectory only at the integrator's 2nd-order level."""
    robot = js2()
    tau = np.array([0.05, -0.2, 0.08, 0.03, -0.02, 0.015])
    q0 = np.array([0.2, 0.1, -0.3, 0.0, 0.4, 0.0])
    start = robot.drives.motor_from_joint(q0)
    a, b = Plant(robot), Plant(robot)
    for p in (a, b):
        p.reset(q0)
    for _ in range(100):
        a.step(tau, 0.004)
        b.step(tau, 0.002)
        b.step(tau, 0.002)
    np.testing.assert_array_equal(a.q_motor, b.q_motor)
    np.testing.assert_array_equal(a.dq_motor, b.dq_motor)
    travel = np.abs(a.q_motor - start).max()
    assert travel > 1.0                                                   # it moved (rad, motor side)
    fine = Plant(robot, truth=load_truth(robot).replace(substeps=8))
    fine.reset(q0)
    for _ in range(200):
        fine.step(tau, 0.002)
    rel = np.abs(fine.q_motor - a.q_motor).max() / travel
    assert rel < 1e-3, rel


def test_truth_from_path_and_defaults():
    robot = js2()
    truth = load_truth(robot.sim_truth_path, n=robot.drives.n)
    plant = Plant(robot, truth=robot.sim_truth_path)
    np.testing.assert_array_equal(plant.truth.static, truth.static)
    assert plant.h_max == pytest.approx(1.0 / (robot.drives.cycle_hz * truth.substeps))
    assert truth.without_friction().coulomb.sum() == 0 and truth.coulomb.sum() > 0


@pytest.mark.parametrize("coupling", ["js2", "tx40"])
def test_fast_and_general_code_paths_agree(tmp_path, coupling):
    """The inlined fast path (ABA with armature) and the general path (a zero-amplitude cogging effect forces the
    force-vector path; a non-diagonal armature forces CRBA + solve) integrate the same physics: same
    trajectory, sticking and sliding, to round-off."""
    robot = js2() if coupling == "js2" else make_robot(tmp_path, K=K_TX40)
    zero_cogging = [{"kind": "cogging", "joints": [0, 1, 2, 3, 4, 5], "amplitude": 0.0, "periods_per_rev": 5}]
    plants = [Plant(robot), Plant(robot, effects=zero_cogging)]
    assert plants[0]._simple == (coupling == "js2") and not plants[1]._simple
    ref = Reference(robot)
    q0 = np.array([0.1, 0.4, -0.6, 0.3, 0.5, -0.3])
    for p in plants:
        p.reset(q0)
    stuck_seen = sliding_seen = False
    for k in range(600):
        t = k * 0.002
        tau = ref.gravity_motor(plants[0].q_joint) + 2.0 * ref.fs * np.sin(2 * np.pi * 1.3 * t + np.arange(6))
        for p in plants:
            p.step(tau, 0.002)
        np.testing.assert_allclose(plants[1].q_motor, plants[0].q_motor, rtol=0, atol=1e-11)
        stuck_seen |= plants[0].stuck.any()
        sliding_seen |= not plants[0].stuck.any()
    assert stuck_seen and sliding_seen
