"""Stiction and friction of the plant, recovered by the paper's own sequential tests (eq. 2-5) run on it."""
from __future__ import annotations

import numpy as np
import pytest

from hil_sim.plant import Plant
from test_sim_support import K_TX40, Reference, breakaway, constant_speed, js2, make_robot

POSE = np.array([0.0, 0.3, -0.5, 0.4, 0.6, 0.2])     # joint angles, rad: every axis carries some gravity


def test_axis_at_rest_stays_until_net_torque_exceeds_static_friction():
    robot = js2()
    ref = Reference(robot)
    plant = Plant(robot)
    hold = ref.gravity_motor(POSE)
    for axis in range(plant.n):
        for frac, moves in ((0.97, False), (1.03, True)):
            plant.reset(POSE)
            tau = hold.copy()
            tau[axis] += frac * ref.fs[axis]
            for _ in range(100):
                plant.step(tau, 0.002)
            moved = np.abs(plant.q_motor - robot.drives.motor_from_joint(POSE))
            if moves:
                assert moved[axis] > 1e-3, (axis, frac)
            else:
                assert moved.max() == 0.0, (axis, frac)      # truly at rest, not creeping
                assert plant.stuck.all()


@pytest.mark.parametrize("axis", [1, 2, 4])
def test_static_ramp_recovers_static_friction_and_gravity(axis):
    """Eq. 3: f_s = (tau+ - tau-)/2, eq. 4: gravity = (tau+ + tau-)/2, within 2 %."""
    robot = js2()
    ref = Reference(robot)
    plant = Plant(robot)
    hold = ref.gravity_motor(POSE)
    start = 0.9 * hold[axis]          # not the answer: the ramp starts 10 % off the gravity torque
    taus = []
    for direction in (+1, -1):
        plant.reset(POSE)
        taus.append(breakaway(plant, axis, hold, direction, rate=0.01, start=start))
    tau_plus, tau_minus = taus
    fs = (tau_plus - tau_minus) / 2
    gravity = (tau_plus + tau_minus) / 2
    assert fs == pytest.approx(ref.fs[axis], rel=0.02)
    assert abs(gravity - hold[axis]) < 0.02 * max(abs(hold[axis]), ref.fs[axis])
    assert abs(hold[axis]) > 0.5 * ref.fs[axis]        # the pose really loads this axis


@pytest.mark.parametrize("axis", [0, 1, 4])
def test_constant_speed_recovers_viscous_and_coulomb(axis):
    """Eq. 5: tau - gravity = B w + f_c sgn(w), several speeds, both directions; B and f_c within 2 %."""
    robot = js2()
    ref = Reference(robot)
    plant = Plant(robot, seed=2)
    speeds, torques = [], []
    for speed in (30.0, 60.0, 120.0, -30.0, -60.0, -120.0):
        w, t = constant_speed(plant, ref, axis, speed, q0=POSE)
        assert w == pytest.approx(speed, rel=0.02)
        speeds.append(w)
        torques.append(t)
    speeds, torques = np.array(speeds), np.array(torques)
    A = np.column_stack([speeds, np.sign(speeds)])
    (B, fc), *_ = np.linalg.lstsq(A, torques, rcond=None)
    assert B == pytest.approx(ref.B[axis], rel=0.02)
    assert fc == pytest.approx(ref.fc[axis], rel=0.02)


def test_stuck_axes_on_coupled_wrist_hold_exactly(tmp_path):
    """With a coupled K (general path), a stuck motor stays at exactly zero velocity while its neighbour moves."""
    robot = make_robot(tmp_path, K=K_TX40)
    ref = Reference(robot)
    plant = Plant(robot)
    plant.reset(POSE)
    hold = ref.gravity_motor(POSE)
    tau = hold.copy()
    tau[4] += 3 * ref.fs[4]               # motor 5 breaks away and drags joint 6 through the coupling
    q5_before = plant.q_motor[5]
    for _ in range(50):
        plant.step(tau, 0.002)
    assert abs(plant.q_motor[4] - robot.drives.motor_from_joint(POSE)[4]) > 1e-2
    assert plant.q_motor[5] == q5_before and plant.dq_motor[5] == 0.0
    assert plant.stuck[5] and not plant.stuck[4]


def test_sliding_axis_stops_and_sticks():
    """A spinning axis with no torque decelerates (Coulomb + viscous) and stops for good (no chatter)."""
    robot = js2()
    ref = Reference(robot)
    plant = Plant(robot)
    plant.reset(POSE)
    hold = ref.gravity_motor(POSE)
    q = robot.drives.motor_from_joint(POSE)
    dq = np.zeros(plant.n)
    dq[0] = 20.0
    plant.set_state(q, dq)
    for _ in range(200):
        plant.step(hold, 0.002)
    assert plant.dq_motor[0] == 0.0 and plant.stuck[0]
    q_stop = plant.q_motor[0]
    assert q_stop > q[0]
    for _ in range(100):
        plant.step(hold, 0.002)
    assert plant.q_motor[0] == q_stop


@pytest.mark.parametrize("coupling", ["js2", "tx40"])
def test_stuck_axes_constraint_solve_balances_eq1(tmp_path, coupling):
    """For every size of stuck set, the plant's constrained solve gives a_S = 0 and the holding torque lam_S such
    that eq. 1 (independent RNEA + motor terms) balances: tau - lam = K^T rnea + J_a a + B w + f_c sgn(w)."""
    robot = js2() if coupling == "js2" else make_robot(tmp_path, K=K_TX40)
    plant = Plant(robot)
    ref = Reference(robot)
    d = plant.dyn
    rng = np.random.default_rng(11)
    for size in range(1, plant.n + 1):
        for _ in range(3):
            stuck = np.zeros(plant.n, dtype=bool)
            stuck[rng.choice(plant.n, size, replace=False)] = True
            q = np.linalg.solve(ref.K, rng.uniform(-1.2, 1.2, plant.n))
            dq = rng.uniform(-100, 100, plant.n) * ~stuck
            tau = rng.uniform(-0.2, 0.2, plant.n)
            Q = tau - ref.B * dq - ref.fc * np.sign(dq)
            solvers = [d.solve] + ([d.solve_fast] if d.fast else [])
            for solve in solvers:
                a, lam = solve(q, dq, Q, stuck)
                assert np.all(a[stuck] == 0.0)
                assert np.all(lam[~stuck] == 0.0)
                np.testing.assert_allclose(tau - lam, ref.motor_torque(q, dq, a), rtol=0, atol=1e-12)
