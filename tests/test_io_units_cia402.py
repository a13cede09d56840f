"""Driver-layer pieces without a bus: unit conversion (the one place), the CiA 402 state machine on both sides,
fault specs, bus options, software limits."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hil_sim.drives_core import DriveCore, Fault
from js2io import cia402
from js2io.bus import bus_kwargs
from js2io.group import motor_position_limits
from js2io.units import Scaling
from js2spec.errors import ConfigError, Js2Error
from js2spec.robot import load_robot

ROBOT = load_robot("js2")


def test_scaling_device_units_to_si():
    s = Scaling.from_drives(ROBOT.drives)
    assert np.allclose(s.position_si([4096] * 6), 2 * math.pi)
    assert np.allclose(s.torque_si([1000] * 6), ROBOT.drives.rated_torque)
    assert np.allclose(s.current_si([500] * 6), np.asarray(ROBOT.drives.rated_current) / 2)
    tau = np.array([0.1234, -0.05, 0.01, 0.0, -0.09, 0.03])
    p = s.torque_permille(tau)
    assert np.all(np.abs(s.torque_si(p) - tau) <= s.rated_torque / 2000 + 1e-15)
    # 0x6072 never above the configured limit, even when the limit is not a whole per-mille
    lim = np.array([0.30049, 0.3, 0.15, 0.09, 0.09, 0.0999])
    assert np.all(s.torque_si(s.torque_limit_permille(lim)) <= lim + 1e-15)
    assert s.torque_limit_permille(lim)[0] == 939


def test_master_walks_drive_to_enabled_and_resets_fault():
    d = DriveCore(0.1, 3.3, 4096, 0.002)
    cw = 0
    for _ in range(6):
        cw = cia402.next_controlword(cia402.state_of(d.statusword()), "enabled", cw)
        d.on_controlword(cw)
    assert d.state == cia402.ENABLED and cia402.state_of(d.statusword()) == cia402.ENABLED
    assert d.fault(0x2310) and not d.fault(0x2310)
    d.torque(0)                         # fault reaction completes within a period
    assert cia402.state_of(d.statusword()) == cia402.FAULT and d.error_code == 0x2310
    d.on_controlword(cia402.CW_ENABLE)  # no rising edge on bit 7: stays in FAULT
    assert d.state == cia402.FAULT
    seen = []
    for _ in range(8):
        cw = cia402.next_controlword(cia402.state_of(d.statusword()), "enabled", cw)
        d.on_controlword(cw)
        seen.append(cw)
    assert cia402.CW_FAULT_RESET in seen and d.state == cia402.ENABLED and d.error_code == 0


def test_drive_limits_torque_and_internal_quick_stop_latches():
    d = DriveCore(0.1, 3.3, 4096, 0.002)
    d.max_torque = 900
    for cw in (6, 7, 15):
        d.on_controlword(cw)
    d.target_torque = 2000
    d.update_velocity(0)
    tau, _ = d.torque(0)
    assert tau == pytest.approx(0.09) and d.statusword() & 0x0800
    assert d.quick_stop()
    d.on_controlword(cia402.CW_ENABLE)          # a quick stop raised by the drive is not undone by 0x0F
    assert d.state == cia402.QUICK_STOP
    d.on_controlword(cia402.CW_DISABLE_VOLTAGE)
    assert d.state == cia402.SWITCH_ON_DISABLED
    d.pos_max = 100
    for cw in (6, 7, 15):
        d.on_controlword(cw)
    _, code = d.torque(101)                      # beyond the software limit 0x607D
    assert code == 0x8612


def test_fault_spec_parsing():
    f = Fault.parse("lost_frames:1@200x20")
    assert (f.kind, f.drive, f.at_cycle, f.count) == ("lost_frames", 1, 200, 20)
    assert Fault.parse("bus_error@400").drive is None
    with pytest.raises(ConfigError, match="unknown fault kind"):
        Fault.parse("meteor:1@3")
    with pytest.raises(ConfigError, match="needs a drive index"):
        Fault.parse("drive_fault@3")


def test_bus_options_like_python_can_tools():
    assert bus_kwargs("socketcan", "can0", 1000000) == {"interface": "socketcan", "channel": "can0",
                                                        "bitrate": 1000000}
    kw = bus_kwargs("socketcand", "js2", None, ["port=4000"])
    assert kw == {"interface": "socketcand", "channel": "js2", "host": "127.0.0.1", "port": 4000, "tcp_tune": True}
    with pytest.raises(Js2Error, match="KEY=VALUE"):
        bus_kwargs("virtual", "x", None, ["oops"])


def test_motor_limits_contain_the_joint_envelope_with_coupled_wrist():
    d = ROBOT.drives
    lo, hi = motor_position_limits(d)
    rng = np.random.default_rng(0)
    q = rng.uniform(d.position_min, d.position_max, size=(2000, d.n))
    m = (np.linalg.inv(np.asarray(d.gear_ratio_matrix)) @ q.T).T
    assert np.all(m >= lo) and np.all(m <= hi)


def test_cli_errors_are_one_line(tmp_path, capsys):
    from js2io.cli import main
    assert main(["--trial", "static", "-o", str(tmp_path / "x.mcap"), "--robot", "nonexistent-arm"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("js2-acquire: error:") and err.count("\n") == 1 and "Traceback" not in err
    assert main(["--trial", "bogus", "-o", str(tmp_path / "x.mcap")]) == 2
    assert "unknown trial 'bogus'" in capsys.readouterr().err
    assert main(["--trial", "static", "-o", str(tmp_path / "x.mcap"), "-i", "nosuchinterface", "-c", "x"]) == 2
    assert "cannot open the CAN bus" in capsys.readouterr().err


def test_cli_names_the_silent_node(tmp_path, capsys):
    """A bus without drives: the master says which node did not answer and what to check."""
    from hil_sim.bus_hub import CanHub
    from js2io.cli import main
    hub = CanHub().start()
    try:
        rc = main(["--trial", "static", "-o", str(tmp_path / "x.mcap"), "-i", "socketcand", "-c", "js2",
                   "--bus-arg", f"port={hub.port}", "--no-progress"])
    finally:
        hub.stop()
    err = capsys.readouterr().err
    assert rc == 2 and "node 1: no SDO answer" in err and "check that the drive" in err, err
    assert not (tmp_path / "x.mcap").exists()


def test_sdo_configuration_reaches_the_drives():
    """After CanopenDriveGroup.open(): 0x6072, 0x607D, 0x6060, heartbeats and the PDO mapping are what the master
    wrote, as seen inside the simulated drives (their object dictionaries and state)."""
    import struct
    from hil_sim.canopen_inprocess import InProcessCanopen
    from js2io.group import motor_position_limits_counts
    with InProcessCanopen(ROBOT) as rig:
        g = rig.group
        g.open()
        fb = g.cycle(None)          # one SYNC: the drives build their PDOs from the mapping the master wrote
        assert fb.valid.all()
        lo, hi = motor_position_limits_counts(ROBOT.drives, g.scaling)
        for i, (core, node) in enumerate(zip(rig.sim.set.cores, rig.sim.nodes)):
            assert core.max_torque == int(np.floor(ROBOT.drives.torque_limit[i] / ROBOT.drives.rated_torque[i] * 1000
                                                   + 1e-9))
            assert (core.pos_min, core.pos_max) == (lo[i], hi[i])
            assert core.mode == core.mode_display == cia402.MODE_CST
            assert rig.sim._hb_consumer[i] == (0x7F, 300)
            assert node.nmt.state == "OPERATIONAL"
            cob, st, idx = rig.sim._tpdo[i]
            assert cob == 0x180 + g.node_ids[i] and idx == [0x6041, 0x6064, 0x6078] and st.size == 8
            assert rig.sim._rpdo[i][0][1] == [0x6040, 0x6071]
            assert struct.unpack("<H", node.get_data(0x1017, 0))[0] == 100
        assert g.source == "hil_sim" and g.source_detail == "hil_sim:canopen"


def test_trials_config_refuses_unknown_keys_and_bad_poses(tmp_path):
    import yaml
    from js2io.trials import TrialContext, load_trials_config, make_trials
    c = yaml.safe_load(ROBOT.trials_path.read_text())
    c["static"]["ramp_rates"] = c["static"].pop("ramp_rate")
    p = tmp_path / "t.yaml"
    p.write_text(yaml.safe_dump(c))
    with pytest.raises(ConfigError, match=r"static.ramp_rates.*unknown key"):
        load_trials_config(p)
    c["static"]["ramp_rate"] = c["static"].pop("ramp_rates")
    c["static"]["poses"] = [[0.0, 1.69, 0.0, 0.0, 0.0, 0.0]]       # inside the envelope but not the margin
    p.write_text(yaml.safe_dump(c))
    ctx = TrialContext(ROBOT.drives, 0.002, load_trials_config(p))
    with pytest.raises(ConfigError, match=r"static.poses\[0\].*outside the joint envelope"):
        make_trials(["static"], ctx)


def test_cli_output_checked_before_the_bus(tmp_path, capsys):
    """-o that would lose data or cannot be written: one line, exit 2, nothing sent, nothing overwritten."""
    from js2io.cli import main
    old = tmp_path / "old.mcap"
    old.write_bytes(b"precious")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    cases = [(old, "the file exists; pass --force"), (tmp_path, "is a folder"),
             (tmp_path / "no" / "such" / "x.mcap", "does not exist; create it")]
    import os
    if os.geteuid() != 0:        # root writes anywhere: the permission case only means something for users
        cases.append((ro / "x.mcap", "is not writable"))
    for path, what in cases:
        assert main(["--trial", "static", "-o", str(path), "--no-progress"]) == 2, path
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and what in err and "Traceback" not in err, err
    assert old.read_bytes() == b"precious"
    assert not (tmp_path / "no").exists()


def test_cli_warns_of_faults_that_never_fire(tmp_path, capsys):
    from js2io.cli import main
    rc = main(["--trial", "validation", "--direct", "-o", str(tmp_path / "x.mcap"), "--no-progress",
               "--sim-fault", "drive_fault:1@999999"])
    cap = capsys.readouterr()
    assert rc == 0
    assert "lies after the planned session" in cap.err
    assert "WARNING: --sim-fault drive_fault:1@999999: never fired" in cap.out
