"""Robot and drive files: the built-in Js-2 loads; bad files give one clear error naming the file and key."""
import shutil

import numpy as np
import pytest
import yaml

from js2spec.drives import parse_drives
from js2spec.errors import ConfigError
from js2spec.robot import load_robot


def test_js2_loads_with_coupled_wrist():
    robot = load_robot("js2")
    d = robot.drives
    assert d.joints == ["j1", "j2", "j3", "j4", "j5", "j6"]
    assert d.K[4, 5] != 0 and d.K[5, 4] != 0          # differential wrist couples motors 5 and 6
    q_motor = np.array([10.0, -20.0, 5.0, 1.0, 3.0, -7.0])
    np.testing.assert_allclose(d.motor_from_joint(d.joint_from_motor(q_motor)), q_motor, atol=1e-12)
    tau_joint = np.array([1.0, 2.0, 3.0, 0.4, 0.5, 0.6])
    # power balance: tau_motor . dq_motor == tau_joint . dq_joint
    tau_motor = d.motor_torque_from_joint(tau_joint)
    dq_motor = np.arange(1.0, 7.0)
    assert np.isclose(tau_motor @ dq_motor, tau_joint @ d.joint_velocity_from_motor(dq_motor))
    assert robot.sim_truth_path is not None and d.torque_limit is not None


def _copy_js2(tmp_path):
    dst = tmp_path / "arm"
    shutil.copytree(load_robot("js2").folder, dst)
    return dst


def _edit_drives(folder, fn):
    p = folder / "drives.yaml"
    d = yaml.safe_load(p.read_text())
    fn(d)
    p.write_text(yaml.safe_dump(d))
    return p


@pytest.mark.parametrize("edit, key", [
    (lambda d: d.pop("torque_constant"), "torque_constant"),
    (lambda d: d.__setitem__("gear_ratio_matrix", [[0.01] * 6] * 6), "gear_ratio_matrix"),
    (lambda d: d.__setitem__("gear_ratio_matrix", [[1, 0], [0, 1]]), "gear_ratio_matrix"),
    (lambda d: d.__setitem__("torque_constant", [0.06, -0.06, 0.045, 0.03, 0.03, 0.03]), "torque_constant"),
    (lambda d: d.__setitem__("torque_side", "wrist"), "torque_side"),
    (lambda d: d["can"].__setitem__("node_ids", [1, 2, 3, 4, 5, 5]), "can.node_ids"),
    (lambda d: d["limits"].__setitem__("torque", [30.0] * 6), "limits.torque"),
])
def test_bad_drives_file_names_file_and_key(tmp_path, edit, key):
    folder = _copy_js2(tmp_path)
    path = _edit_drives(folder, edit)
    with pytest.raises(ConfigError) as err:
        load_robot(folder)
    assert err.value.key == key
    assert str(path) in str(err.value) and key in str(err.value)


def test_negative_mass_and_bad_inertia_are_refused(tmp_path):
    folder = _copy_js2(tmp_path)
    urdf = folder / "robot.urdf"
    text = urdf.read_text()
    urdf.write_text(text.replace('<mass value="2.0"/>', '<mass value="-2.0"/>'))
    with pytest.raises(ConfigError, match=r"link\[link2\].inertial.mass.*> 0"):
        load_robot(folder)
    urdf.write_text(text.replace('ixx="0.0030"', 'ixx="-0.0030"'))
    with pytest.raises(ConfigError, match=r"link\[link2\].inertial.inertia"):
        load_robot(folder)


def test_urdf_joints_must_match_drives(tmp_path):
    folder = _copy_js2(tmp_path)
    _edit_drives(folder, lambda d: d.__setitem__("joints", ["j1", "j2", "j3", "j4", "j5", "wrist_roll"]))
    with pytest.raises(ConfigError, match="wrist_roll"):
        load_robot(folder)


def test_unknown_robot_lists_known_ones():
    with pytest.raises(ConfigError, match="unknown robot.*js2"):
        load_robot("no_such_arm")


def test_parse_drives_rejects_non_mapping():
    with pytest.raises(ConfigError, match="mapping"):
        parse_drives([1, 2, 3], "x.yaml")


def test_rest_speed_is_the_joint_side_min_speed_at_each_motor():
    """js2spec.drives.motor_rest_speed / at_rest: the one rest rule of the diagnosis and hil_sim's replay. On the
    Js-2 (1:100 ... 1:50 gears, a differential wrist) 0.01 rad/s at the joints is 1 rad/s at a 1:100 motor; a motor
    turning at its rest speed moves its fastest joint at exactly min_speed; a direct drive keeps the number."""
    from js2spec.drives import at_rest, motor_rest_speed

    K = load_robot("js2").drives.K
    v = motor_rest_speed(0.01, K)
    np.testing.assert_allclose(v, [1.0, 1.0, 0.8, 0.5, 1.0, 1.0], rtol=1e-12)
    np.testing.assert_allclose(np.max(np.abs(K * v[None, :]), axis=0), 0.01, rtol=1e-12)
    assert np.all(np.abs(K[:, 4:] * v[None, 4:]) <= 0.01 * (1 + 1e-12))    # wrist: no joint faster than min_speed
    np.testing.assert_array_equal(motor_rest_speed(0.02, np.eye(3)), [0.02, 0.02, 0.02])
    speed = np.array([v * (1 - 1e-9), -v, -0.999 * v, 1.5 * v])
    speed[2, 0] = np.nan                                           # a lost sample
    np.testing.assert_array_equal(at_rest(speed, v), np.repeat([[True], [False], [True], [False]], 6, axis=1))
