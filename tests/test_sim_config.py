"""Bad simulator configs give one clear ConfigError naming the file and the key."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from hil_sim.effects import EFFECT_PARAMS
from hil_sim.plant import Plant
from hil_sim.truth import load_truth
from js2spec.errors import ConfigError
from test_sim_support import js2, make_robot


def _truth_error(tmp_path, mutate):
    robot = make_robot(tmp_path)
    d = yaml.safe_load(robot.sim_truth_path.read_text())
    mutate(d)
    robot.sim_truth_path.write_text(yaml.safe_dump(d))
    with pytest.raises(ConfigError) as exc:
        Plant(robot)
    assert str(robot.sim_truth_path) in str(exc.value)
    return exc.value


@pytest.mark.parametrize("mutate, key, words", [
    (lambda d: d.pop("viscous"), "viscous", "missing"),
    (lambda d: d.update(coulomb=[0.02, -0.01, 0.01, 0.01, 0.005, 0.005]), "coulomb", ">= 0"),
    (lambda d: d.update(motor_inertia=[3e-5, 0.0, 1e-5, 1e-5, 1e-5, 1e-5]), "motor_inertia", "> 0"),
    (lambda d: d.update(static=[0.001] * 6), "static", "coulomb"),
    (lambda d: d.update(viscous=[1e-4] * 5), "viscous", "one entry per drive"),
    (lambda d: d.update(stiction_velocity=1e-3), "stiction_velocity", "unknown key"),
    (lambda d: d.update(integration={"substeps": 0}), "integration.substeps", ">= 1"),
    (lambda d: d.update(sensors={"current_noise_std": [-1] * 6}), "sensors.current_noise_std", ">= 0"),
    (lambda d: d.update(effects=[{"kind": "magic_friction", "joints": [0]}]), "effects[0].kind", "unknown effect"),
    (lambda d: d.update(effects=[{"kind": "stribeck", "joints": [0], "velocity": 1.0, "speed": 2}]),
     "effects[0].speed", "unknown parameter"),
    (lambda d: d.update(effects=[{"kind": "stribeck", "joints": [0]}]), "effects[0].velocity", "missing"),
    (lambda d: d.update(effects=[{"kind": "stribeck", "joints": [0], "velocity": -1.0}]), "effects[0].velocity",
     "> 0"),
    (lambda d: d.update(effects=[{"kind": "cogging", "joints": [9], "amplitude": 0.01, "periods_per_rev": 4}]),
     "effects[0].joints", "not a joint"),
    (lambda d: d.update(effects=[{"kind": "joint_elasticity", "stiffness": 100.0}]), "effects[0].joints", "missing"),
    (lambda d: d.update(effects=[{"kind": "backlash", "joints": [2], "width": 0.01}]), "effects[0].stiffness",
     "contact stiffness"),
    (lambda d: d.update(effects=[{"kind": "asymmetric_friction", "joints": [1], "negative_scale": 1.2},
                                 {"kind": "asymmetric_friction", "joints": [1], "negative_scale": 1.3}]),
     "effects[1].joints", "twice"),
    (lambda d: d.update(effects=[{"kind": "payload_change", "mass": -5.0}]), "effects[0].mass", "> 0"),
    (lambda d: d.update(effects=[{"kind": "payload_change", "mass": 0.1, "com": [0.1, 0.0]}]), "effects[0].com",
     "3"),
])
def test_bad_truth_names_file_and_key(tmp_path, mutate, key, words):
    err = _truth_error(tmp_path, mutate)
    assert f"'{key}'" in str(err), str(err)
    assert words in str(err), str(err)
    assert "\n" not in str(err)


def test_effects_argument_is_validated_too():
    robot = js2()
    with pytest.raises(ConfigError, match=r"effects\[0\]\.kind.*unknown effect 'wobble'"):
        Plant(robot, effects=[{"kind": "wobble", "joints": [0]}])
    with pytest.raises(ConfigError, match=r"effects\[0\]\.amplitude"):
        Plant(robot, effects=[{"kind": "cogging", "joints": ["j2"], "periods_per_rev": 4}])


def test_missing_truth_file_and_joint_names(tmp_path):
    robot = make_robot(tmp_path)
    robot.sim_truth_path.unlink()
    with pytest.raises(ConfigError, match="sim_truth.yaml.*not found"):
        load_truth(robot)
    robot = js2()
    plant = Plant(robot, effects=[{"kind": "asymmetric_friction", "joints": ["j2", 4], "negative_scale": 2.0}])
    assert plant.friction.negative_scale.tolist() == [1.0, 2.0, 1.0, 1.0, 2.0, 1.0]


def test_every_documented_effect_builds_with_its_required_parameters():
    robot = js2()
    required = {"stribeck": {"velocity": 2.0}, "cogging": {"amplitude": 0.001, "periods_per_rev": 8},
                "payload_change": {"mass": 0.2}, "thermal_drift": {"heating": 10.0, "time_constant": 60.0,
                                                                   "friction_per_kelvin": 0.005},
                "load_dependent_friction": {"coefficient": 0.05}, "asymmetric_friction": {"negative_scale": 1.2},
                "joint_elasticity": {"stiffness": 3000.0}, "backlash": {"width": 0.002, "stiffness": 3000.0},
                "torque_offset": {"offset": 0.02}, "coupling": {"from_joint": 2, "coefficient": 0.05}}
    assert set(required) == set(EFFECT_PARAMS)
    for kind, params in required.items():
        plant = Plant(robot, effects=[{"kind": kind, "joints": [1], **params}])
        plant.reset()
        plant.step(plant.gravity_torque(), 0.01)
        assert np.all(np.isfinite(plant.q_joint))


def test_non_finite_torque_is_refused_and_state_kept():
    import numpy as np
    import pytest

    from hil_sim.plant import Plant
    from js2spec.robot import load_robot

    plant = Plant(load_robot("js2"), seed=0)
    plant.reset()
    q0 = plant.q_motor.copy()
    with pytest.raises(ValueError, match="finite"):
        plant.step(np.array([0.0, np.nan, 0.0, 0.0, 0.0, 0.0]), 0.002)
    assert np.array_equal(plant.q_motor, q0) and np.all(np.isfinite(plant.dq_motor))
