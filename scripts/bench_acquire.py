#!/usr/bin/env python3
"""Benchmark the acquisition cycle against the simulated drives, in real time.

For each transport -- `virtual` (master and simulated drives in one process) and `socketcand` (js2-sim in its own
process, as `js2-acquire --realtime` runs it) -- it runs the full cycle (SYNC, 6 RPDOs, 6 TPDOs, CiA 402 master
logic, a trial controller, the MCAP log, the session's default safety settings) paced by the wall clock for --seconds,
optionally beside --load N CPU-bound processes, and prints: missed cycles (SYNC deadlines overrun by more than a period,
skipped), stale cycles (some drive's TPDO not back before the deadline), SYNC period jitter p50/p99/max, and whether
the run completed or ABORTED (then the exit code is 1), beside the highest rate the CAN bus allows for the EDS's PDO
layout at 1 Mbit/s. `--lockstep` adds a run without pacing (the CPU ceiling).

  .venv/bin/python scripts/bench_acquire.py                      # 60 s per run, both transports
  .venv/bin/python scripts/bench_acquire.py --load 2 --rt-priority 50   # two CPU-bound processes beside it
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


def bus_limit_hz(robot, bitrate=1_000_000, worst=True) -> tuple[float, int, tuple[int, int]]:
    """SYNC + per drive the RPDO sent every cycle (controlword + torque) and the feedback TPDO, sized from the EDS."""
    from js2io.pdo import CONTROLWORD, read_layout
    lay = read_layout(robot.eds_path)
    rpdo, tpdo = lay.rpdo_with(CONTROLWORD).codec.size, lay.feedback.codec.size
    n = robot.drives.n
    bits = frame_bits(0, worst) + n * (frame_bits(rpdo, worst) + frame_bits(tpdo, worst))
    return bitrate / bits, bits, (rpdo, tpdo)


def make_trial(robot, seconds, cycle_hz):
    from js2io.trials import FourierTrial, TrialContext, load_trials_config
    cfg = load_trials_config(robot.trials_path)
    cfg["excitation"].update(period_s=max(2.0, seconds / 2), periods=max(1.0, (seconds - 4) / max(2.0, seconds / 2)),
                             fade_s=1.0)
    return FourierTrial(TrialContext(robot.drives, 1.0 / cycle_hz, cfg))


SYNC = "auto"


def run(make_rig, robot, seconds, cycle_hz):
    """One session (the master's default safety settings, as js2-acquire runs it) on a fresh rig."""
    from js2io.session import Session, open_log
    with tempfile.TemporaryDirectory() as d:
        rig = make_rig()
        try:
            group = rig.group
            group.keep_sync_times = True
            group.sync_mode = SYNC
            group.open()
            w = open_log(Path(d) / "bench.mcap", robot, group)
            trial = make_trial(robot, seconds, cycle_hz)
            s = Session(group, w, [trial])
            t0 = time.perf_counter()
            res = s.run()
            wall = time.perf_counter() - t0
        finally:
            rig.close()
    st = np.asarray(group.sync_times)
    out = {"cycles": res.cycles, "wall": wall, "rate": res.cycles / wall, "stale": res.invalid_cycles,
           "stale_per_drive": res.stale, "missed": getattr(group, "missed", 0), "aborted": res.aborted,
           "reason": res.reason, "sim": getattr(rig, "summary", lambda: "")()}
    rt = np.asarray(getattr(group, "round_trips", []), dtype=float)
    if rt.size and np.isfinite(rt).any():
        out.update(rtt_p50=float(np.nanpercentile(rt, 50)) * 1e6, rtt_p99=float(np.nanpercentile(rt, 99)) * 1e6)
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


def virtual_rig(robot, cycle_hz, realtime, faults):
    """Master and simulated drives in one process on python-can's virtual bus (physics one period per SYNC)."""
    def f():
        from hil_sim.canopen_inprocess import InProcessCanopen
        return InProcessCanopen(robot, cycle_hz=cycle_hz, realtime=realtime, sim_realtime=False, faults=faults,
                                lockstep_timeout_s=0.25).start()
    return f


RT_PRIO = 0
SIM_CPU = None


def socketcand_rig(robot, cycle_hz, realtime, faults):
    """js2-sim in its own process (its own interpreter), the master here over socketcand: as js2-acquire --realtime."""
    def f():
        from hil_sim.rigs import ProcessRig
        return ProcessRig(robot, cycle_hz=cycle_hz, realtime=realtime, faults=faults, rt_priority=RT_PRIO,
                          cpu=SIM_CPU).start()
    return f


def timer_baseline(rate, seconds) -> str:
    """The machine's own floor: an empty loop paced like the cycle (sleep to absolute deadlines, same scheduling, same
    load): how late it wakes. A cycle cannot be more punctual than this."""
    from js2io.canopen_group import _sleep_until
    dt = 1.0 / rate
    n = int(seconds * rate)
    late = np.empty(n)
    nxt = time.perf_counter()
    for k in range(n):
        nxt += dt
        _sleep_until(nxt)
        late[k] = time.perf_counter() - nxt
    late *= 1e6
    return (f"timer baseline (empty loop at {rate:g} Hz, {seconds:g} s, same scheduling and load): wake-up late "
            f"p50 {np.percentile(late, 50):.0f} us, p99 {np.percentile(late, 99):.0f} us, max {late.max():.0f} us, "
            f"{int((late > 0.9 * dt * 1e6).sum())} of {n} wake-ups later than 0.9 period")


def _normal_scheduling() -> None:
    """In a load process, before exec: never inherit the bench's SCHED_FIFO or CPU pinning (two real-time busy
    loops would take both cores from everything, the bench included)."""
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    os.sched_setaffinity(0, range(os.cpu_count()))


def start_load(n: int) -> list:
    """n CPU-bound background processes at normal priority on any CPU (what else runs on a cell's PC)."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"], preexec_fn=_normal_scheduling)
             for _ in range(n)]
    for p in procs:
        if os.sched_getscheduler(p.pid) != os.SCHED_OTHER:
            stop_load(procs)
            raise RuntimeError("a load process kept real-time scheduling; refusing to run")
    return procs


def stop_load(procs) -> None:
    for p in procs:
        p.kill()
    for p in procs:
        p.wait()


def fmt_run(tr, r, rate, seconds, lim) -> str:
    n_exp = max(1, r["cycles"] + r["missed"])
    j = [r.get(k, float("nan")) for k in ("jitter_p50", "jitter_p99", "jitter_max")]
    head = (f"[{tr}] real time at {rate:g} Hz for {seconds:g} s: achieved {r['rate']:.1f} Hz "
            f"({100 * r['rate'] / lim:.0f} % of the bus limit), cycles {r['cycles']}, "
            f"missed {r['missed']} ({100 * r['missed'] / n_exp:.2f} %), "
            f"stale {r['stale']} ({100 * r['stale'] / max(1, r['cycles']):.2f} %; per drive {r['stale_per_drive']}), "
            f"SYNC jitter p50 {j[0]:.0f} us, p99 {j[1]:.0f} us, max {j[2]:.0f} us"
            + (f", TPDO round trip p50 {r['rtt_p50']:.0f} us, p99 {r['rtt_p99']:.0f} us (of complete cycles)"
               if "rtt_p50" in r else ""))
    return head + (f"; ABORTED: {r['reason']}" if r["aborted"] else "; completed")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="length of each real-time run (default 60)")
    ap.add_argument("--rate", type=float, help="SYNC rate (default: 90 %% of the 1 Mbit/s bus limit)")
    ap.add_argument("--transport", choices=["virtual", "socketcand", "both"], default="both")
    ap.add_argument("--load", type=int, default=0, metavar="N",
                    help="N CPU-bound background processes during the measurement (default 0)")
    ap.add_argument("--lockstep", action="store_true", help="also measure the lock-step CPU ceiling (10 s each)")
    ap.add_argument("--fault", action="append", default=[], metavar="KIND[:DRIVE][@CYCLE][xCOUNT]",
                    help="inject a simulator fault (e.g. drive_fault:2@300) -- the run aborts, the exit code says so")
    ap.add_argument("--profile", action="store_true", help="cProfile the main thread in a lock-step run")
    ap.add_argument("--rt-priority", type=int, default=0, metavar="N",
                    help="SCHED_FIFO priority for master and simulator, memory locked (Linux, root/CAP_SYS_NICE); 0 = off")
    ap.add_argument("--cpu", type=int, metavar="C",
                    help="pin the master to CPU C and the socketcand simulator process to another (Linux)")
    ap.add_argument("--sync", choices=["auto", "master", "periodic"], default="auto",
                    help="who produces SYNC (as js2-acquire --sync; auto = master on these transports)")
    ap.add_argument("--baseline-s", type=float, default=5.0, help="length of the timer baseline (0 = skip)")
    args = ap.parse_args()
    global RT_PRIO, SIM_CPU, SYNC
    RT_PRIO = args.rt_priority
    SYNC = args.sync
    from js2io.rt import realtime_setup
    from js2spec.errors import Js2Error
    if args.cpu is not None:
        others = sorted(set(os.sched_getaffinity(0)) - {args.cpu})
        SIM_CPU = others[0] if others else args.cpu
    try:
        sched = realtime_setup(args.rt_priority, args.cpu)
    except Js2Error as e:
        print(f"bench_acquire: error: {e}", file=sys.stderr)
        return 2
    import logging
    logging.basicConfig(level=logging.ERROR)
    from js2io.bus import quiet_socketcand
    from js2spec.robot import load_robot
    quiet_socketcand()
    robot = load_robot("js2")
    lim, bits, (rb, tb) = bus_limit_hz(robot)
    lim_typ, bits_typ, _ = bus_limit_hz(robot, worst=False)
    rate = args.rate or round(0.9 * lim)
    print(f"CAN bus limit, SYNC + 6 x RPDO({rb} B) + 6 x TPDO({tb} B) (the EDS's layout) at 1 Mbit/s: {bits} bits/cycle "
          f"worst-case stuffing -> {lim:.0f} Hz ({bits_typ} bits without stuffing -> {lim_typ:.0f} Hz); "
          f"90 % = {0.9 * lim:.0f} Hz")
    transports = ["virtual", "socketcand"] if args.transport == "both" else [args.transport]
    fac = {"virtual": virtual_rig, "socketcand": socketcand_rig}
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
        r = run(fac[transports[0]](robot, rate, False, args.fault), robot, min(args.seconds, 10), rate)
        pr.disable()
        print(f"lock-step {transports[0]}: {r['rate']:.0f} cycles/s")
        pstats.Stats(pr).sort_stats("tottime").print_stats(18)
        return 0
    load = start_load(args.load)
    aborted = []
    try:
        time.sleep(1.0 if load else 0.0)     # let the load reach the scheduler before measuring
        print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} (1 min; includes other work on "
              f"it), --load {args.load} (background CPU-bound processes, normal scheduling); SYNC {args.sync}; python {sys.version.split()[0]}; {sched}",
              flush=True)
        if args.baseline_s > 0:
            print(timer_baseline(rate, args.baseline_s), flush=True)
        for tr in transports:
            if args.lockstep:
                r = run(fac[tr](robot, rate, False, args.fault), robot, min(args.seconds, 10), rate)
                print(f"[{tr}] lock-step (CPU ceiling, no pacing): {r['cycles']} cycles in {r['wall']:.1f} s = "
                      f"{r['cycles'] / r['wall']:.0f} cycles/s")
            r = run(fac[tr](robot, rate, True, args.fault), robot, args.seconds, rate)
            print(fmt_run(tr, r, rate, args.seconds, lim), flush=True)
            if r["sim"]:
                print(f"    {r['sim']}")
            if r["aborted"]:
                aborted.append(tr)
        print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    finally:
        stop_load(load)
    if aborted:
        print(f"bench_acquire: {len(aborted)} run(s) ABORTED ({', '.join(aborted)}): the figures above are not a "
              f"completed measurement", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
