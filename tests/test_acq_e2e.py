"""Across processes: `js2-sim` serves its drives on the loopback socketcand hub, `js2-acquire` runs a trial against
it from another process. Plus: the slcan (USB adapter) path through a pty, Ctrl-C/SIGTERM, and a killed writer."""
from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import can
import numpy as np
import pytest

from test_acq_support import short_trials_yaml
from js2spec.log import read_log

BIN = Path(sys.executable).parent


def _start_sim(*extra):
    p = subprocess.Popen([str(BIN / "js2-sim"), "--port", "0", *extra], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True)
    lines = []
    port = None
    t_end = time.monotonic() + 60
    while time.monotonic() < t_end:
        line = p.stdout.readline()
        if not line:
            break
        lines.append(line)
        m = re.search(r"PORT (\d+)", line)
        if m:
            port = int(m.group(1))
            break
    if port is None:
        p.kill()
        pytest.fail("js2-sim did not report its port:\n" + "".join(lines))
    return p, port


def test_sim_and_acquire_in_two_processes(tmp_path):
    sim, port = _start_sim()
    try:
        out = tmp_path / "xp.mcap"
        r = subprocess.run([str(BIN / "js2-acquire"), "-i", "socketcand", "-c", "js2", "--bus-arg", f"port={port}",
                            "--trial", "static,acceleration", "-o", str(out), "--config",
                            str(short_trials_yaml(tmp_path / "t.yaml")), "--no-progress"],
                           capture_output=True, text=True, timeout=240)
        assert r.returncode == 0, r.stdout + r.stderr
        assert "socketcand" in r.stderr
    finally:
        sim.send_signal(signal.SIGTERM)
        rest = sim.communicate(timeout=30)[0]
    assert sim.returncode == 0, rest
    m = re.search(r"(\d+) SYNCs served, hub relayed (\d+) frames, (\d+) dropped", rest)
    assert m and int(m.group(1)) > 1000 and int(m.group(3)) == 0, rest
    log = read_log(out)
    assert log.source == "hil_sim:canopen"
    assert log.trials() == ["static", "acceleration"]
    assert len([e for e in log.events if e["kind"] == "breakaway"]) == 4
    assert np.all(np.diff(log.feedback.cycle) == 1) and log.feedback.valid.all()
    assert int(m.group(1)) >= len(log.feedback.cycle)


def test_slcan_pty_smoke():
    """A python-can slcan bus (the USB-CAN adapter protocol, via pyserial) on the hub's pty talks to a socketcand
    client: frames pass both ways."""
    from hil_sim.bus_hub import CanHub
    from js2io.bus import open_bus

    hub = CanHub().start()
    try:
        pty = hub.add_slcan_pty()
        sl = open_bus({"interface": "slcan", "channel": pty, "bitrate": 1000000, "sleep_after_open": 0.05})
        sc = open_bus({"interface": "socketcand", "channel": "js2", "host": "127.0.0.1", "port": hub.port,
                       "tcp_tune": True})
        try:
            time.sleep(0.1)
            sl.send(can.Message(arbitration_id=0x181, data=bytes([1, 2, 3, 4, 5, 6, 7, 8]), is_extended_id=False))
            m = sc.recv(2.0)
            assert m is not None and m.arbitration_id == 0x181 and bytes(m.data) == bytes(range(1, 9))
            sc.send(can.Message(arbitration_id=0x080, data=b"", is_extended_id=False))
            sc.send(can.Message(arbitration_id=0x201, data=bytes([0x0F, 0, 0x10, 0]), is_extended_id=False))
            got = []
            t_end = time.monotonic() + 2.0
            while len(got) < 2 and time.monotonic() < t_end:
                m = sl.recv(0.5)
                if m is not None:
                    got.append((m.arbitration_id, bytes(m.data)))
            assert got == [(0x080, b""), (0x201, bytes([0x0F, 0, 0x10, 0]))]
        finally:
            sl.shutdown()
            sc.shutdown()
        st = hub.stats()
        assert st["frames"] == 3 and sum(e["dropped"] for e in st["endpoints"]) == 0
    finally:
        hub.stop()


def test_hub_drops_oldest_when_a_reader_stalls():
    """A client that never reads must not block the others: its queue drops the oldest frames, counted."""
    import socket
    from hil_sim.bus_hub import CanHub
    from js2io.bus import open_bus

    hub = CanHub(max_queue=50).start()
    try:
        stalled = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        stalled.connect(("127.0.0.1", hub.port))
        stalled.recv(64)
        stalled.sendall(b"< open js2 >")
        time.sleep(0.05)
        stalled.recv(64)
        stalled.sendall(b"< rawmode >")
        time.sleep(0.05)
        stalled.recv(64)
        a = open_bus({"interface": "socketcand", "channel": "js2", "host": "127.0.0.1", "port": hub.port})
        b = open_bus({"interface": "socketcand", "channel": "js2", "host": "127.0.0.1", "port": hub.port})
        try:
            import threading
            N = 20000
            got = []

            def reader():
                t_end = time.monotonic() + 30
                while len(got) < N and time.monotonic() < t_end:
                    m = b.recv(0.5)
                    if m is not None:
                        got.append(int.from_bytes(m.data, "little"))

            th = threading.Thread(target=reader)
            th.start()
            for k in range(N):
                a.send(can.Message(arbitration_id=0x100 + (k % 16), data=k.to_bytes(4, "little"), is_extended_id=False))
                if k % 50 == 49:
                    time.sleep(0.002)   # a bus-like pace the live reader can follow
            th.join()
            assert got == list(range(N)), f"the live client got {len(got)} of {N} frames (in order)"
            drops = [e["dropped"] for e in hub.stats()["endpoints"]]
            assert max(drops) > 0 and sorted(drops)[:2] == [0, 0], drops
        finally:
            a.shutdown()
            b.shutdown()
            stalled.close()
    finally:
        hub.stop()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_ramps_down_disables_and_closes(tmp_path, sig):
    out = tmp_path / "int.mcap"
    p = subprocess.Popen([str(BIN / "js2-acquire"), "--trial", "velocity", "-o", str(out), "--no-progress"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t_end = time.monotonic() + 60
    while time.monotonic() < t_end and (not out.exists() or out.stat().st_size < 200_000):
        time.sleep(0.1)
    p.send_signal(sig)
    so, se = p.communicate(timeout=60)
    assert p.returncode == 1, so + se
    log = read_log(out)
    assert not log.truncated
    ab = [e for e in log.events if e["kind"] == "abort"]
    assert ab and f"interrupted ({sig.name})" in ab[-1]["detail"]
    # the last commands ramp to zero, and the drives end disabled
    tt = log.command.target_torque
    assert np.all(tt[-1] == 0.0)
    k_ab = np.searchsorted(log.command.t, ab[-1]["t"])
    ramp = np.abs(tt[k_ab:]).max(axis=1)
    assert np.all(np.diff(ramp[: int(0.3 * 500)]) <= 1e-9), "torques must ramp down monotonically"
    assert all(s & 0x4F == 0x40 for s in log.feedback.status[-1]), log.feedback.status[-1]
    assert np.all(np.abs(tt) <= np.asarray(log.drives.torque_limit) + 1e-12)


def test_killed_writer_leaves_readable_log(tmp_path):
    out = tmp_path / "kill.mcap"
    p = subprocess.Popen([str(BIN / "js2-acquire"), "--trial", "static", "-o", str(out), "--no-progress", "--direct"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t_end = time.monotonic() + 60
    while time.monotonic() < t_end and (not out.exists() or out.stat().st_size < 300_000):
        time.sleep(0.05)
    p.kill()
    p.wait(timeout=10)
    log = read_log(out)
    assert log.truncated
    assert len(log.feedback.t) > 1000
    assert [e["kind"] for e in log.events][:1] == ["trial_start"]


def _acquire_velocity_until_logging(port, out):
    """js2-acquire's velocity trial against the js2-sim at `port`, returned once its log holds 100 kB (mid-trial)."""
    acq = subprocess.Popen([str(BIN / "js2-acquire"), "-i", "socketcand", "-c", "js2", "--bus-arg", f"port={port}",
                            "--trial", "velocity", "-o", str(out), "--no-progress"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t_end = time.monotonic() + 60
    while time.monotonic() < t_end and (not out.exists() or out.stat().st_size < 100_000):
        time.sleep(0.05)
    return acq


def test_simulator_process_killed_mid_trial(tmp_path):
    """The far side vanishes (js2-sim SIGKILLed): the master notices (lost TPDOs / heartbeats / bus), stops safely,
    and the log is complete with the reason."""
    sim, port = _start_sim()
    out = tmp_path / "gone.mcap"
    acq = _acquire_velocity_until_logging(port, out)
    try:
        sim.kill()
        so, se = acq.communicate(timeout=120)
    finally:
        if acq.poll() is None:
            acq.kill()
        sim.kill()
        sim.wait()
    assert acq.returncode == 1, so + se
    assert "ABORTED" in so and "Traceback" not in se
    log = read_log(out)
    assert not log.truncated
    kinds = [e["kind"] for e in log.events]
    assert "abort" in kinds and "fault" in kinds
    why = " ".join(e.get("detail", "") for e in log.events if e["kind"] in ("fault", "abort"))
    assert any(w in why for w in ("bus error", "heartbeat lost", "TPDOs lost")), why
    # the summary claims nothing it could not confirm, and every reason is one line
    end = so.split("drives at the end:")[1].splitlines()[0]
    assert "OPERATION ENABLED" not in end and "NOT CONFIRMED DISABLED (no answer)" in end, so
    assert all("\n" not in e.get("detail", "") for e in log.events)
    assert "Traceback" not in so


def _statuswords_over_sdo(port, robot="js2"):
    """Ask every simulated drive for its statusword (0x6041) over SDO, as a service tool would."""
    import canopen

    from js2spec.robot import load_robot
    rb = load_robot(robot)
    net = canopen.Network(can.Bus(interface="socketcand", channel="js2", host="127.0.0.1", port=port))
    net.connect()
    try:
        out = []
        for nid in range(1, rb.drives.n + 1):
            node = canopen.RemoteNode(nid, str(rb.eds_path))
            net.add_node(node)
            out.append(int(node.sdo[0x6041].raw))
        return out
    finally:
        net.disconnect()


def test_simulator_frozen_mid_trial(tmp_path):
    """js2-sim SIGSTOPped (a hung drive process): the master aborts in one line, claims no drive disabled it could
    not confirm, leaves a readable log; once the drives run again they are out of OPERATION ENABLED by themselves
    (the master's heartbeat is gone), asked over SDO."""
    from js2io import cia402
    sim, port = _start_sim()
    out = tmp_path / "frozen.mcap"
    acq = _acquire_velocity_until_logging(port, out)
    try:
        sim.send_signal(signal.SIGSTOP)
        so, se = acq.communicate(timeout=120)
        sim.send_signal(signal.SIGCONT)
        time.sleep(1.5)        # > 3 x the master's heartbeat period: the drives' consumer has timed out
        states = [cia402.state_of(s) for s in _statuswords_over_sdo(port)]
    finally:
        if acq.poll() is None:
            acq.kill()
        sim.send_signal(signal.SIGCONT)
        sim.kill()
        sim.wait()
    assert acq.returncode == 1, so + se
    assert "Traceback" not in so + se
    reason = [ln for ln in so.splitlines() if ln.startswith("ABORTED:")]
    assert len(reason) == 1 and any(w in reason[0] for w in ("TPDOs lost", "heartbeat", "bus error")), so
    end = so.split("drives at the end:")[1].splitlines()[0]
    assert "OPERATION ENABLED" not in end and "NOT CONFIRMED DISABLED (no answer)" in end, so
    log = read_log(out)
    assert "abort" in [e["kind"] for e in log.events]
    assert np.all(np.abs(log.command.target_torque) <= np.asarray(log.drives.torque_limit) + 1e-12)
    assert cia402.ENABLED not in states, states


def test_killed_writer_then_repair_opens_in_generic_readers(tmp_path):
    """kill -9 of the master mid-trial: mcap's own reader gets nothing out of the file (no footer); js2-repair makes
    it a complete MCAP with every recoverable message."""
    from mcap.reader import make_reader
    out = tmp_path / "kill.mcap"
    p = subprocess.Popen([str(BIN / "js2-acquire"), "--trial", "static", "-o", str(out), "--no-progress", "--direct"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t_end = time.monotonic() + 60
    while time.monotonic() < t_end and (not out.exists() or out.stat().st_size < 300_000):
        time.sleep(0.05)
    p.kill()
    p.wait(timeout=10)
    n = len(read_log(out).feedback)
    r = subprocess.run([str(BIN / "js2-repair"), str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "truncated" in r.stdout, r.stdout + r.stderr
    with open(tmp_path / "kill.repaired.mcap", "rb") as f:
        assert sum(1 for _ in make_reader(f).iter_messages(topics=["/js2/feedback"])) == n


def _small_disk(tmp_path):
    """A 300 kB tmpfs if this machine lets us mount one (root), else None."""
    import os
    d = tmp_path / "small"
    d.mkdir()
    if os.geteuid() != 0:
        return None
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(d)], capture_output=True)
    return d if r.returncode == 0 else None


def test_full_disk_cli(tmp_path):
    """`js2-acquire -o` on a disk that fills up mid-trial (a real 300 kB tmpfs where we may mount one, else a
    300 kB file-size limit): exit 1, the drives confirmed disabled, the log failure in one line after them."""
    import resource
    small = _small_disk(tmp_path)
    out = (small or tmp_path) / "x.mcap"

    def limit():                 # fallback: the kernel refuses writes beyond 300 kB (EFBIG), like a full disk
        if small is None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (300_000, 300_000))
    try:
        r = subprocess.run([str(BIN / "js2-acquire"), "--trial", "static", "-o", str(out), "--no-progress"],
                           capture_output=True, text=True, timeout=300, preexec_fn=limit)
    finally:
        if small is not None:
            subprocess.run(["umount", str(small)])
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    assert "drives at the end: " + ", ".join(["SWITCH ON DISABLED"] * 6) in r.stdout, r.stdout
    assert "ABORTED: log write failed" in r.stdout and "LOG INCOMPLETE" in r.stdout
