"""js2-acquire: run identification trials on an arm through its CANopen drives and write a js2 log.

  js2-acquire --trial all -o run.mcap                        # in-process simulator on python-can's virtual bus
  js2-acquire --trial excitation -o x.mcap --realtime        # simulator in its own process, SYNC on the wall clock
  js2-acquire --trial static -o s.mcap -i socketcan -c can0 -b 1000000 --realtime      # a real arm (SocketCAN)
  js2-acquire --trial velocity -o v.mcap -i socketcand -c js2 --bus-arg port=PORT     # js2-sim in another process
"""
from __future__ import annotations

import argparse
import signal
import sys
import time

from js2spec.errors import Js2Error


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="js2-acquire", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n", 2)[2])
    p.add_argument("--trial", default="all",
                   help="static, velocity, acceleration, excitation, validation, all, or a comma list (default all)")
    p.add_argument("-o", "--output", help="the js2 log to write (.mcap); its folder must exist")
    p.add_argument("--force", action="store_true", help="overwrite an existing -o file")
    p.add_argument("--dry-run", action="store_true", help="check the configuration and print the trial plan; no bus")
    p.add_argument("--robot", default="js2", help="robot name under configs/ or a robot folder (default js2)")
    p.add_argument("--config", help="trials file (default: the robot's trials.yaml)")
    p.add_argument("--seed", type=int, default=0, help="seed for trajectories and the simulator's noise")
    p.add_argument("--cycle-hz", type=float, help="SYNC rate (default: drives.yaml can.cycle_hz)")
    p.add_argument("--realtime", action="store_true",
                   help="pace SYNC by the wall clock (needed for real drives); default: lock-step, SYNC as soon as "
                        "all drives answered (simulators only)")
    p.add_argument("--sync", choices=["auto", "master", "periodic"], default="auto",
                   help="real time: who produces SYNC -- master (the cycle loop, at each deadline), periodic (python-can's "
                        "periodic send: kernel-timed on SocketCAN, a thread elsewhere), auto (periodic on SocketCAN)")
    g = p.add_argument_group("CAN bus (as python-can's tools take it; none given = in-process simulator)")
    g.add_argument("-i", "--interface", help="python-can interface: socketcan, socketcand, slcan, pcan, virtual, ...")
    g.add_argument("-c", "--channel", help="channel, e.g. can0, /dev/ttyACM0")
    g.add_argument("-b", "--bitrate", type=int, help="bit rate, e.g. 1000000")
    g.add_argument("--bus-arg", action="append", default=[], metavar="KEY=VALUE",
                   help="extra python-can Bus argument, e.g. --bus-arg port=29536 (repeatable)")
    g.add_argument("--bus-config", action="store_true", help="open the bus from python-can's config file/environment")
    s = p.add_argument_group("simulated drives (no bus given)")
    s.add_argument("--sim", metavar="NAME",
                   help="the simulated rig, chosen by name from the installed drive groups (entry points "
                        "'js2.drive_groups'): sim (in this process, python-can's virtual bus; the default), sim-direct "
                        "(no CAN, fastest), sim-process (js2-sim in its own process; the default with --realtime)")
    s.add_argument("--direct", action="store_true", help="same as --sim sim-direct")
    s.add_argument("--sim-fault", action="append", default=[], metavar="KIND[:DRIVE][@CYCLE][xCOUNT]",
                   help="inject a fault: dead_node, lost_frames, drive_fault, bus_error, heartbeat_loss; "
                        "e.g. drive_fault:2@3000 (repeatable)")
    p.add_argument("--max-lost", type=int, default=10, help="consecutive lost TPDOs of one drive that abort (default 10)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--joint-state", action="store_true",
                   help="also log /js2/joint_state (joint side, for viewers such as Foxglove)")
    p.add_argument("--rt-priority", type=int, default=0, metavar="N",
                   help="run the cycle loop with SCHED_FIFO priority N and lock its memory (Linux; root/CAP_SYS_NICE; "
                        "says so and stops when not permitted); 0 = off")
    p.add_argument("--cpu", type=int, metavar="C",
                   help="run the cycle loop on CPU C only (Linux); with --sim sim-process the simulator takes another")
    return p


def plan_text(robot, cfg, trials, cycle_hz) -> str:
    lines = [f"robot {robot.name} ({robot.folder}), trials file {cfg.get('_path')}, {cycle_hz:g} Hz"]
    total = 0.0
    for t in trials:
        est = t.estimate_s()
        total += est
        extra = ""
        if t.name == "static":
            extra = f"{len(t.poses)} poses x {len(t.axes)} axes x {len(t.directions)} directions"
        elif t.name == "velocity":
            runs = {i: len(t.runs(i)[1]) for i in t.axes}
            extra = f"{t.mode}, speeds per axis {runs} (x2 directions), steady <= {t.steady_s:g} s"
        elif t.name == "acceleration":
            extra = f"{len(t._plan)} strokes, durations {t.durations}"
        else:
            extra = f"period {t.period:g} s x {t.periods:g}, {t.harmonics} harmonics"
        lines.append(f"  {t.name:<12} ~{est:6.1f} s  {extra}")
    lines.append(f"  total        ~{total:6.1f} s of arm time")
    return "\n".join(lines)


def _fault_cycles(specs, trials, cycle_hz) -> list[tuple[str, int]]:
    """(spec, cycle) of each --sim-fault 'KIND[:DRIVE][@CYCLE][xCOUNT]' (the simulated rig parses and checks the
    rest when it opens, before any trial). A fault timed after the planned session is said at once."""
    import re
    planned = int(sum(t.estimate_s() for t in trials) * cycle_hz)
    out = []
    for s in specs:
        m = re.search(r"@(\d+)", s)
        at = int(m.group(1)) if m else 0
        if at > planned:
            print(f"js2-acquire: warning: --sim-fault {s}: cycle {at} lies after the planned session "
                  f"(~{planned} cycles); it will not fire unless the trials run longer", file=sys.stderr)
        out.append((s, at))
    return out


def check_output(path: str, force: bool) -> None:
    """Refuse, before any bus traffic, an -o that would lose data or cannot be written."""
    import os
    from pathlib import Path
    out = Path(path)
    if out.is_dir():
        raise Js2Error(f"-o {path}: is a folder; give a file name, e.g. {out / 'session.mcap'}")
    if out.exists() and not force:
        raise Js2Error(f"-o {path}: the file exists; pass --force to overwrite it or choose another name")
    folder = out.parent
    if not folder.is_dir():
        raise Js2Error(f"-o {path}: the folder {folder} does not exist; create it (mkdir -p {folder}) or fix the path")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise Js2Error(f"-o {path}: the folder {folder} is not writable; choose another -o")


def _other_cpu(cpu):
    """A CPU for a simulator process beside a master pinned to `cpu` (None: no pinning)."""
    import os
    if cpu is None or not hasattr(os, "sched_getaffinity"):
        return None
    others = sorted(set(os.sched_getaffinity(0)) - {cpu}) or [cpu]
    return others[0]


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from js2io.bus import console_logging
    console_logging("js2-acquire")
    try:
        return _run(args)
    except Js2Error as e:
        print(f"js2-acquire: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("js2-acquire: interrupted", file=sys.stderr)
        return 130


def _run(args) -> int:
    from js2spec.robot import load_robot

    from .bus import bus_kwargs, open_bus
    from .session import Session, open_log
    from .trials import TrialContext, expand_trial_names, load_trials_config, make_trials

    from .rt import realtime_setup
    robot = load_robot(args.robot)
    sched = realtime_setup(args.rt_priority, args.cpu)
    cfg_path = args.config or robot.trials_path
    if cfg_path is None:
        from .trials import default_trials_path
        cfg_path = default_trials_path()
    cfg = load_trials_config(cfg_path)
    names = expand_trial_names(args.trial)
    use_bus = bool(args.interface or args.channel or args.bus_config or args.bus_arg)
    if use_bus and (args.direct or args.sim_fault or args.sim):
        raise Js2Error("--sim, --direct and --sim-fault apply to the simulated drives only; drop the bus options or them")
    if args.direct and args.sim and args.sim != "sim-direct":
        raise Js2Error(f"--direct and --sim {args.sim} contradict each other; keep one")
    sim_name = "sim-direct" if args.direct else (args.sim or ("sim-process" if args.realtime else "sim"))
    sim = None
    bus = None
    network = None
    group = None
    cycle_hz = args.cycle_hz or robot.drives.cycle_hz or 500.0
    ctx = TrialContext(robot.drives, 1.0 / cycle_hz, cfg, seed=args.seed)
    trials = make_trials(names, ctx)
    if args.dry_run:
        print(plan_text(robot, cfg, trials, cycle_hz))
        return 0
    if not args.output:
        raise Js2Error("-o/--output FILE.mcap is required (or --dry-run)")
    check_output(args.output, args.force)
    faults = _fault_cycles(args.sim_fault, trials, cycle_hz)
    try:
        if use_bus:
            import canopen

            from .canopen_group import CanopenDriveGroup
            kw = {} if args.bus_config else bus_kwargs(args.interface, args.channel, args.bitrate, args.bus_arg)
            bus = open_bus(kw)
            where = f"CAN bus {bus.channel_info}"
            network = canopen.Network(bus)
            network.connect()
            if robot.eds_path is None:
                raise Js2Error(f"{robot.folder}: no drives.eds (the drives' object dictionary); add it")
            group = CanopenDriveGroup(robot.drives, network, robot.eds_path, cycle_hz=cycle_hz,
                                      realtime=args.realtime)
        else:
            from .rigs import open_rig
            sim = open_rig(sim_name, robot, cycle_hz=cycle_hz, seed=args.seed, faults=args.sim_fault,
                           realtime=args.realtime, rt_priority=args.rt_priority, cpu=_other_cpu(args.cpu))
            group, where = sim.group, sim.where
        if hasattr(group, "sync_mode"):
            group.sync_mode = args.sync
        print(f"js2-acquire: {robot.name}, trials {', '.join(names)} -> {args.output} ({where}, "
              f"{cycle_hz:g} Hz, {'real time' if args.realtime else 'lock-step'}, {sched})", file=sys.stderr)
        group.open()
        try:
            writer = open_log(args.output, robot, group, cfg)
        except OSError as e:
            raise Js2Error(f"cannot write the log {args.output}: {e.strerror or e}; choose another -o path") from None
        session = Session(group, writer, trials, progress=not args.no_progress, max_consecutive_lost=args.max_lost,
                          joint_state=args.joint_state)

        def on_signal(signum, frame):
            session.stop_request = signal.Signals(signum).name

        old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            res = session.run()
        finally:
            for s_, h in old.items():
                signal.signal(s_, h)
        for spec, at in faults:
            if at >= res.cycles:
                res.warnings.append(f"--sim-fault {spec}: never fired (the session ended at cycle {res.cycles}, "
                                    f"before cycle {at})")
        print(res.text())
        return 1 if res.aborted else 0
    finally:
        if group is not None:
            group.close()
        if network is not None:
            try:
                network.disconnect()
            except Exception:
                pass
        elif bus is not None:
            bus.shutdown()
        if sim is not None:
            sim.close()


if __name__ == "__main__":
    raise SystemExit(main())
