#!/usr/bin/env python3
"""Benchmark the acquisition cycle against the simulated drives, in real time.

For each transport it runs the full cycle (SYNC, 6 RPDOs, 6 TPDOs, CiA 402 master logic, a trial controller, the MCAP
log) paced by the wall clock for --seconds, and prints the achieved cycle rate, missed cycles (SYNC sent more than one
period late, or a drive's TPDO not back before the next SYNC), SYNC period jitter p50/p99, beside the highest rate the
CAN bus itself allows for this PDO layout at 1 Mbit/s. A lock-step run (no pacing) gives the CPU ceiling.

  .venv/bin/python scripts/bench_acquire.py                      # 60 s per run, both transports
  .venv/bin/python scripts/bench_acquire.py --seconds 10 --transport virtual --rate 500
  .venv/bin/python scripts/bench_acquire.py --profile            # where the main thread's time goes (lock-step)
"""
from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def frame_bits(n_bytes: int, worst: bool = True) -> int:
    """CAN 2.0A frame incl. 3-bit interframe space; worst-case stuffing: one bit per 4 after the first of the
    34 + 8n stuffable bits (SOF .. CRC)."""
    base = 47 + 8 * n_bytes
    return base + ((33 + 8 * n_bytes) // 4 if worst else 0)


def bus_limit_hz(n_drives=6, rpdo=4, tpdo=8, bitrate=1_000_000, worst=True) -> tuple[float, int]:
    bits = frame_bits(0, worst) + n_drives * (frame_bits(rpdo, worst) + frame_bits(tpdo, worst))
    return bitrate / bits, bits


def make_trial(robot, seconds, cycle_hz):
    from js2io.trials import FourierTrial, TrialContext, load_trials_config
    cfg = load_trials_config(robot.trials_path)
    cfg["excitation"].update(period_s=max(2.0, seconds / 2), periods=max(1.0, (seconds - 4) / max(2.0, seconds / 2)),
                             fade_s=1.0)
    return FourierTrial(TrialContext(robot.drives, 1.0 / cycle_hz, cfg))


def run(group_factory, robot, seconds, cycle_hz, realtime):
    from js2io.session import Session, open_log
    with tempfile.TemporaryDirectory() as d:
        group, closer = group_factory()
        try:
            group.keep_sync_times = True
            group.open()
            w = open_log(Path(d) / "bench.mcap", robot, group)
            trial = make_trial(robot, seconds, cycle_hz)
            s = Session(group, w, [trial], max_consecutive_lost=10 ** 9)
            t0 = time.perf_counter()
            res = s.run()
            wall = time.perf_counter() - t0
        finally:
            closer()
    st = np.asarray(group.sync_times)
    out = {"cycles": res.cycles, "wall": wall, "rate": res.cycles / wall, "invalid": res.invalid_cycles,
           "missed_sync": getattr(group, "missed", 0), "aborted": res.reason}
    if len(st) > 10:
        per = np.diff(st)
        jit = np.abs(per - 1.0 / cycle_hz) * 1e6
        out.update(rate=(len(st) - 1) / (st[-1] - st[0]), jitter_p50=float(np.percentile(jit, 50)),
                   jitter_p99=float(np.percentile(jit, 99)), jitter_max=float(jit.max()))
    return out


def component_costs(robot, cycle_hz, n=3000) -> list[tuple[str, float]]:
    """Mean CPU time per cycle of each piece of the loop, measured in isolation (us)."""
    import can
    from hil_sim.drives_core import SimDriveSet
    from js2io.session import open_log
    from hil_sim.direct import DirectDriveGroup

    out = []
    sim = SimDriveSet(robot, cycle_hz=cycle_hz)
    t = time.perf_counter()
    for _ in range(n):
        sim.plant.step(np.zeros(6), 1.0 / cycle_hz)
    out.append(("simulator: plant.step (physics, one period)", (time.perf_counter() - t) / n))
    t = time.perf_counter()
    for _ in range(n):
        sim.on_sync(step=False)
    out.append(("simulator: 6 CiA 402 drive models + sensors", (time.perf_counter() - t) / n))
    g = DirectDriveGroup(robot, cycle_hz=cycle_hz)
    g.open()
    trial = make_trial(robot, 20, cycle_hz)
    fb = g.sync()
    t = time.perf_counter()
    for _ in range(n):
        trial.step(fb)
    out.append(("master: trial controller (reference + PID)", (time.perf_counter() - t) / n))
    with tempfile.TemporaryDirectory() as d:
        w = open_log(Path(d) / "x.mcap", robot, g)
        t = time.perf_counter()
        for k in range(n):
            w.feedback(k, k / cycle_hz, fb.motor_position, fb.torque, motor_current=fb.motor_current,
                       status=fb.status, valid=fb.valid)
            w.command(k, k / cycle_hz, g.modes, fb.torque)
        out.append(("master: MCAP log (feedback + command, JSON, zstd)", (time.perf_counter() - t) / n))
        w.close()
    from js2io.cia402 import next_controlword
    t = time.perf_counter()
    cmd = trial.step(fb).command
    for _ in range(n):
        g.clamp_permille(cmd.target_torque)
        [next_controlword("OPERATION ENABLED", "enabled", 15) for _ in range(6)]
        g.scaling.position_si(fb.counts), g.scaling.current_si(fb.counts)
    out.append(("master: units + CiA 402 logic", (time.perf_counter() - t) / n))
    a = can.Bus(interface="virtual", channel="bench-cost")
    b = can.Bus(interface="virtual", channel="bench-cost")
    m = can.Message(arbitration_id=0x181, data=bytes(8), is_extended_id=False)
    t = time.perf_counter()
    for _ in range(n):
        for _ in range(13):
            a.send(m)
        for _ in range(13):
            b.recv(0)
    out.append(("python-can: 13 frames send+receive (virtual bus)", (time.perf_counter() - t) / n))
    a.shutdown()
    b.shutdown()
    return [(k, v * 1e6) for k, v in out]


def virtual_factory(robot, cycle_hz, realtime):
    def f():
        from hil_sim.canopen_inprocess import InProcessCanopen
        rig = InProcessCanopen(robot, cycle_hz=cycle_hz, realtime=realtime, sim_realtime=False,
                               lockstep_timeout_s=0.25).start()
        return rig.group, rig.close
    return f


RT_PRIO = 0


def socketcand_factory(robot, cycle_hz, realtime):
    def f():
        import canopen
        from js2io.bus import open_bus
        from js2io.canopen_group import CanopenDriveGroup
        sim = subprocess.Popen([sys.executable, "-m", "hil_sim.cli", "--port", "0", "--cycle-hz", str(cycle_hz),
                                "--rt-priority", str(RT_PRIO)],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT)
        port = None
        for _ in range(20):
            line = sim.stdout.readline()
            m = re.search(r"PORT (\d+)", line)
            if m:
                port = int(m.group(1))
                break
        if port is None:
            sim.kill()
            raise RuntimeError("js2-sim did not start")
        bus = open_bus({"interface": "socketcand", "channel": "js2", "host": "127.0.0.1", "port": port,
                        "tcp_tune": True})
        net = canopen.Network(bus)
        net.connect()
        g = CanopenDriveGroup(robot.drives, net, robot.eds_path, cycle_hz=cycle_hz, realtime=realtime)

        def close():
            g.close()
            net.disconnect()
            sim.send_signal(signal.SIGTERM)
            try:
                print("    " + sim.communicate(timeout=10)[0].strip().splitlines()[-1])
            except Exception:
                sim.kill()
        return g, close
    return f


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="length of each real-time run (default 60)")
    ap.add_argument("--rate", type=float, help="SYNC rate (default: 90 %% of the 1 Mbit/s bus limit)")
    ap.add_argument("--transport", choices=["virtual", "socketcand", "both"], default="both")
    ap.add_argument("--profile", action="store_true", help="cProfile the main thread in a lock-step run")
    ap.add_argument("--rt-priority", type=int, default=0, metavar="N",
                    help="SCHED_FIFO priority for master and simulator (Linux, root/CAP_SYS_NICE); 0 = off")
    args = ap.parse_args()
    global RT_PRIO
    RT_PRIO = args.rt_priority
    from js2io.rt import set_realtime_priority
    sched = set_realtime_priority(args.rt_priority)
    import logging
    logging.basicConfig(level=logging.ERROR)
    from js2io.bus import quiet_socketcand
    from js2spec.robot import load_robot
    quiet_socketcand()
    robot = load_robot("js2")
    lim, bits = bus_limit_hz()
    lim_typ, bits_typ = bus_limit_hz(worst=False)
    rate = args.rate or round(0.9 * lim)
    print(f"CAN bus limit, SYNC + 6 x RPDO(4 B) + 6 x TPDO(8 B) at 1 Mbit/s: {bits} bits/cycle worst-case stuffing "
          f"-> {lim:.0f} Hz ({bits_typ} bits without stuffing -> {lim_typ:.0f} Hz); 90 % = {0.9 * lim:.0f} Hz")
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} (other work on it slows us down); "
          f"python {sys.version.split()[0]}; {sched}")
    transports = ["virtual", "socketcand"] if args.transport == "both" else [args.transport]
    fac = {"virtual": virtual_factory, "socketcand": socketcand_factory}
    if args.profile:
        costs = component_costs(robot, rate)
        print("CPU per cycle, each piece alone (us):")
        for k, v in costs:
            print(f"  {v:7.1f}  {k}")
        print(f"  {sum(v for _, v in costs):7.1f}  total, vs a {1e6 / rate:.0f} us period at {rate:g} Hz "
              f"(+ thread hand-offs: notifier threads, GIL, canopen dispatch)")
        import cProfile
        import pstats
        pr = cProfile.Profile()
        pr.enable()
        r = run(fac[transports[0]](robot, rate, False), robot, min(args.seconds, 10), rate, False)
        pr.disable()
        print(f"lock-step {transports[0]}: {r['rate']:.0f} cycles/s")
        pstats.Stats(pr).sort_stats("tottime").print_stats(18)
        return 0
    for tr in transports:
        r = run(fac[tr](robot, rate, False), robot, min(args.seconds, 10), rate, False)
        print(f"[{tr}] lock-step (CPU ceiling, no pacing): {r['cycles']} cycles in {r['wall']:.1f} s = "
              f"{r['cycles'] / r['wall']:.0f} cycles/s")
        r = run(fac[tr](robot, rate, True), robot, args.seconds, rate, True)
        missed = r["missed_sync"] + r["invalid"]
        print(f"[{tr}] real time at {rate:g} Hz for {args.seconds:g} s: achieved {r['rate']:.1f} Hz "
              f"({100 * r['rate'] / lim:.0f} % of the bus limit), cycles {r['cycles']}, missed {missed} "
              f"(late SYNC {r['missed_sync']}, incomplete TPDO sets {r['invalid']}), "
              f"SYNC jitter p50 {r.get('jitter_p50', float('nan')):.0f} us, p99 {r.get('jitter_p99', float('nan')):.0f}"
              f" us, max {r.get('jitter_max', float('nan')):.0f} us"
              + (f"; ABORTED: {r['aborted']}" if r["aborted"] else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
