"""The ``coupling`` effect (a gear matrix error): its schema and its physics in hil_sim.

The arm's joint-from-motor matrix is K_true = (I + c e_j e_i^T) K; the references below are computed with the test's
own pinocchio model (test_sim_support.Reference) and K_true built here, never the plant's.
"""
from __future__ import annotations

import numpy as np
import pytest

from hil_sim.plant import Plant
from hil_sim.replay import inverse_replay
from hil_sim.truth import load_truth
from js2spec.effects import parse_effects
from js2spec.errors import ConfigError
from test_sim_support import Reference, js2

J, I, C = 4, 3, 0.08          # joint j5 also turns 0.08 rad per rad of joint j4
EFFECT = {"kind": "coupling", "joints": [J], "from_joint": I, "coefficient": C}


def _k_true(robot) -> np.ndarray:
    K = np.asarray(robot.drives.gear_ratio_matrix, float)
    E = np.zeros_like(K)
    E[J, I] = C
    return (np.eye(len(K)) + E) @ K


def _reference(robot) -> Reference:
    ref = Reference(robot)
    ref.K = _k_true(robot)
    return ref


# --- schema -------------------------------------------------------------------------------------------------------
def test_schema_parses_names_and_round_trips():
    robot = js2()
    names = list(robot.drives.joints)
    (e,) = parse_effects([{"kind": "coupling", "joints": ["j5"], "from_joint": "j4", "coefficient": -0.05}], 6,
                         "x.yaml", joints=names)
    assert e.joints == (4,) and e["from_joint"] == 3 and e["coefficient"] == -0.05
    assert parse_effects([e.as_config()], 6, "x.yaml")[0] == e
    # two couplings onto one joint from different joints are two effects; the same pair twice is refused
    assert len(parse_effects([EFFECT, {**EFFECT, "from_joint": 5}], 6, "x.yaml")) == 2
    with pytest.raises(ConfigError, match=r"x\.yaml.*effects\[1\]\.joints.*twice"):
        parse_effects([EFFECT, EFFECT], 6, "x.yaml")


@pytest.mark.parametrize("change, message", [
    ({"from_joint": 4}, r"effects\[0\]\.from_joint.*own joint 4"),
    ({"from_joint": 6}, r"effects\[0\]\.from_joint.*6 is not a joint \(0\.\.5"),
    ({"from_joint": "wrist"}, r"effects\[0\]\.from_joint.*'wrist' is not a joint"),
    ({"from_joint": None}, r"effects\[0\]\.from_joint.*missing \(required parameter of coupling"),
    ({"coefficient": 1.0}, r"effects\[0\]\.coefficient.*between -1 and 1"),
    ({"coefficient": "0.1"}, r"effects\[0\]\.coefficient.*finite number"),
    ({"coefficient": None}, r"effects\[0\]\.coefficient.*missing"),
])
def test_schema_refuses_bad_parameters_with_the_key(change, message):
    item = {k: v for k, v in {**EFFECT, **change}.items() if v is not None}
    with pytest.raises(ConfigError, match=r"sim_truth\.yaml.*" + message):
        parse_effects([item], 6, "sim_truth.yaml", joints=list(js2().drives.joints))


def test_couplings_that_make_the_gear_matrix_singular_are_refused():
    c = float(np.sqrt(0.5))     # det(I + C) = 1 - c^2 - c^2 = 0: joints 1 and 2, 1 and 3 driven as one
    eff = [{"kind": "coupling", "joints": [0], "from_joint": 1, "coefficient": c},
           {"kind": "coupling", "joints": [0], "from_joint": 2, "coefficient": c},
           {"kind": "coupling", "joints": [1], "from_joint": 0, "coefficient": c},
           {"kind": "coupling", "joints": [2], "from_joint": 0, "coefficient": c}]
    with pytest.raises(ConfigError, match="singular"):
        Plant(js2(), effects=eff)


# --- physics ------------------------------------------------------------------------------------------------------
def test_plant_moves_the_joints_as_k_true_says():
    """Link angles and velocities come from the motors through K_true (not the drives' K), while the encoders still
    read the motors: joint j5 is off the drives' reading by c times joint j4's angle."""
    robot = js2()
    K, Kt = np.asarray(robot.drives.gear_ratio_matrix, float), _k_true(robot)
    off = np.asarray(robot.drives.joint_offset, float)
    plant = Plant(robot, effects=[EFFECT], seed=3)
    plant.reset(np.array([0.1, 0.3, -0.4, 0.6, 0.2, -0.1]))
    rng = np.random.default_rng(7)
    for _ in range(200):
        plant.step(plant.gravity_torque() + rng.uniform(-0.05, 0.05, 6), 0.002)
    qm, dqm = plant.q_motor, plant.dq_motor
    assert np.abs(dqm).max() > 1.0                                    # it moved
    np.testing.assert_allclose(plant.q_joint, Kt @ qm + off, rtol=0, atol=1e-12)
    np.testing.assert_allclose(plant.dq_joint, Kt @ dqm, rtol=0, atol=1e-12)
    drives_view = K @ qm + off
    assert plant.q_joint[J] - drives_view[J] == pytest.approx(C * (K @ qm)[I], rel=1e-9)
    np.testing.assert_allclose(np.delete(plant.q_joint - drives_view, J), 0.0, atol=1e-12)
    # the encoders see the motors (what a drive reads is unaffected by the gear error)
    np.testing.assert_allclose(plant.read_sensors().motor_position, qm, atol=2 * np.pi / 4096)


def test_torques_go_through_k_true_transposed():
    """Forward dynamics put back into K_true^T rnea(K_true theta ...) + J_a theta_dd + friction gives the motor torque
    (the plant's acceleration is eq. 1 with K_true), and the inverse replay of a prescribed motion is that torque."""
    robot = js2()
    plant = Plant(robot, effects=[EFFECT])
    ref = _reference(robot)
    rng = np.random.default_rng(11)
    worst = 0.0
    for _ in range(10):
        q_joint = rng.uniform(-1.2, 1.2, 6)
        q_motor = np.linalg.solve(ref.K, q_joint - ref.offset)
        dq_motor = rng.uniform(30, 120, 6) * rng.choice([-1, 1], 6)
        tau = rng.uniform(-0.3, 0.3, 6)
        ddq_motor = plant.forward_dynamics(q_motor, dq_motor, tau)
        worst = max(worst, float(np.max(np.abs(ref.motor_torque(q_motor, dq_motor, ddq_motor) - tau))))
    assert worst < 1e-9, worst
    # the same physics in the replay (model_plant builds a Plant with the effects)
    frictionless = Plant(robot, truth=load_truth(robot).without_friction(), effects=[EFFECT])
    t = np.arange(5) * 0.002
    q, dq, ddq = (rng.normal(size=(5, 6)) * s for s in (3.0, 80.0, 500.0))
    got = inverse_replay(frictionless, t, q, dq, ddq).tau_motor
    want = np.array([ref.motor_torque(q[s], dq[s], ddq[s], friction=False) for s in range(5)])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-10)
    plain = np.array([Reference(robot).motor_torque(q[s], dq[s], ddq[s], friction=False) for s in range(5)])
    assert np.max(np.abs(got - plain)) > 1e-3            # and it is not the drives' K


def test_power_is_consistent_energy_conserved_without_friction():
    """K_true maps both the motion and the torques (power tau_m . theta_m_d = tau . q_d): with friction off and no
    torque, links + rotors kinetic + gravity potential (with K_true) stay constant over 4 s."""
    robot = js2()
    plant = Plant(robot, truth=load_truth(robot).without_friction(), effects=[EFFECT])
    ref = _reference(robot)
    plant.reset(np.array([0.3, 0.2, -0.4, 0.5, 0.8, -0.2]))
    e0 = sum(ref.energy(plant.q_motor, plant.dq_motor))
    worst, ke_max = 0.0, 0.0
    for k in range(2000):
        plant.step(np.zeros(6), 0.002)
        if k % 10 == 9:
            ke, pe = ref.energy(plant.q_motor, plant.dq_motor)
            worst, ke_max = max(worst, abs(ke + pe - e0)), max(ke_max, ke)
    assert ke_max > 1.0
    assert worst / ke_max < 1e-4, (worst, ke_max)
