"""js2-sim: the Js-2 simulator as six CiA 402 drives on a CAN bus, for js2-acquire in another process.

  js2-sim                           # serve a socketcand hub on 127.0.0.1 (ephemeral port, printed) and attach
  js2-sim --port 29536 --slcan-pty  # fixed port, plus an slcan pseudo-terminal (USB-adapter protocol)
  js2-sim -i socketcan -c vcan0     # join an existing bus instead (Linux with vcan/SocketCAN)
  js2-sim --replay run.mcap --model runs/model --effects runs/diag/effects.yaml -o replayed.mcap
                                    # no bus: the recording's motion through the identified model (+ effects)

Physics advances one period per SYNC (lock-step, deterministic) unless --realtime (wall clock).
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading

from js2spec.errors import Js2Error


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="js2-sim", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n", 2)[2])
    p.add_argument("--robot", default="js2")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--cycle-hz", type=float, help="nominal SYNC rate (the physics period in lock-step)")
    p.add_argument("--realtime", action="store_true", help="step the physics on the wall clock instead of per SYNC")
    p.add_argument("--fault", action="append", default=[], metavar="KIND[:DRIVE][@CYCLE][xCOUNT]",
                   help="inject a fault (dead_node, lost_frames, drive_fault, bus_error, heartbeat_loss)")
    p.add_argument("--q0", help="initial joint angles, comma separated (rad)")
    h = p.add_argument_group("served bus (default)")
    h.add_argument("--port", type=int, default=0, help="socketcand hub port on 127.0.0.1 (0 = any free port)")
    h.add_argument("--channel-name", default="js2", help="socketcand channel name the hub accepts")
    h.add_argument("--slcan-pty", action="store_true", help="also expose the bus as an slcan pseudo-terminal")
    b = p.add_argument_group("join an existing bus instead")
    b.add_argument("-i", "--interface")
    b.add_argument("-c", "--channel")
    b.add_argument("-b", "--bitrate", type=int)
    b.add_argument("--bus-arg", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--rt-priority", type=int, default=0, metavar="N",
                   help="SCHED_FIFO priority N for the simulator (Linux; root/CAP_SYS_NICE); 0 = off")
    p.add_argument("--cpu", type=int, metavar="C", help="run the simulator on CPU C only (Linux)")
    p.add_argument("--duration", type=float, help="exit after this many seconds (default: until Ctrl-C/SIGTERM)")
    r = p.add_argument_group("replay a recording instead of serving a bus (hil_sim.replay)")
    r.add_argument("--replay", metavar="RECORDING", help="a js2 log: its recorded motion is replayed through the "
                   "identified model (inverse dynamics: the torque the simulator needs) and compared with its torques")
    r.add_argument("--model", metavar="DIR", help="model.yaml written by js2-identify (or its folder); required "
                   "with --replay")
    r.add_argument("--effects", metavar="YAML", help="effects to add to the model (effects.yaml from js2-diagnose)")
    r.add_argument("-o", "--output", metavar="OUT.mcap", help="the simulated recording (with --replay)")
    r.add_argument("--mode", choices=("inverse", "forward"), default="inverse",
                   help="what OUT.mcap holds: inverse = the recorded positions and the torque the simulator needs "
                        "for them; forward = the positions the simulator reaches under the recorded torque plus a "
                        "tracking term (default inverse; both are compared and printed)")
    r.add_argument("--bandwidth", type=float, default=5.0, metavar="HZ",
                   help="bandwidth of the forward replay's tracking term (default 5 Hz)")
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from js2io.bus import console_logging
    console_logging("js2-sim")
    if args.replay or args.model or args.effects or args.output:
        return _replay(args)
    try:
        return _run(args)
    except Js2Error as e:
        print(f"js2-sim: error: {e}", file=sys.stderr)
        return 2


def _replay(args) -> int:
    """js2-sim --replay RECORDING --model DIR [--effects YAML] -o OUT.mcap: print the per-joint RMS of recording
    minus simulation (moving samples, torque band), with the model and with the model plus the effects."""
    if not (args.replay and args.model and args.output):
        print("js2-sim: error: --replay RECORDING --model DIR -o OUT.mcap go together (--effects YAML optional)",
              file=sys.stderr)
        return 2
    from .replay import replay_recording, write_replay_log
    try:
        if not args.bandwidth > 0:
            raise Js2Error(f"--bandwidth {args.bandwidth}: must be > 0 Hz")
        rep = replay_recording(args.replay, args.model, args.effects, bandwidth_hz=args.bandwidth)
        out = write_replay_log(rep, args.replay, args.model, args.output, args.effects, mode=args.mode)
    except Js2Error as e:
        print(f"js2-sim: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"js2-sim: error: cannot write {e.filename or args.output}: {e.strerror or e}; choose another -o",
              file=sys.stderr)
        return 2
    for note in rep.notes:
        print(f"note: {note}")
    before = rep.rms("model")
    after = rep.rms("effects") if rep.tau_effects is not None else None
    print(f"js2-sim: replayed {args.replay} through {args.model}" + (f" + {args.effects}" if args.effects else "")
          + f" ({len(rep.t)} samples; {args.mode} replay written)\ninverse replay (the recorded motion prescribed): "
            f"RMS recorded - simulated torque on the moving samples, torque band:")
    for i, j in enumerate(rep.joints):
        line = f"  {j:<14} model {before[i]:.4g} N*m"
        if after is not None:
            line += f"   model + effects {after[i]:.4g} N*m"
        print(line)
    kinds = ["model"] + (["effects"] if args.effects else [])
    print(f"forward replay (recorded torque + tracking at {args.bandwidth:g} Hz): RMS recorded - simulated joint "
          f"angle; followed " + ", ".join(f"{k} {rep.followed(k):.0%}" for k in kinds) + " of the samples:")
    pos = {k: rep.position_rms(k) for k in kinds}
    for i, j in enumerate(rep.joints):
        print(f"  {j:<14} " + "   ".join(f"{'model' if k == 'model' else 'model + effects'} {pos[k][i]:.4g} rad"
                                         for k in kinds))
    print(f"-> {out}")
    return 0


def _run(args) -> int:
    import numpy as np

    from js2io.bus import bus_kwargs, open_bus, quiet_socketcand
    from js2spec.robot import load_robot

    from .drives import CanopenSimulator
    from .drives_core import Fault

    from js2io.rt import realtime_setup
    robot = load_robot(args.robot)
    sched = realtime_setup(args.rt_priority, args.cpu)
    faults = [Fault.parse(f) for f in args.fault]
    q0 = None
    if args.q0:
        try:
            q0 = np.array([float(x) for x in args.q0.split(",")])
        except ValueError:
            raise Js2Error(f"--q0 {args.q0!r}: write joint angles in rad separated by commas") from None
    hub = None
    quiet_socketcand()
    if args.interface or args.channel or args.bus_arg:
        kw = bus_kwargs(args.interface, args.channel, args.bitrate, args.bus_arg)
        where = ", ".join(f"{k}={v}" for k, v in kw.items())
    else:
        from .bus_hub import CanHub
        try:
            hub = CanHub(port=args.port).start()
        except OSError as e:
            raise Js2Error(f"cannot listen on 127.0.0.1:{args.port}: {e}; choose another --port (0 = any)") from None
        kw = None
        where = f"socketcand hub 127.0.0.1:{hub.port}"
    # the drives sit on the hub in-process (no TCP for them); clients come in over socketcand/slcan
    bus = hub.local_bus("js2-sim drives") if hub is not None else open_bus(kw)
    sim = CanopenSimulator(robot, bus, cycle_hz=args.cycle_hz, seed=args.seed, faults=faults,
                           realtime=args.realtime, q0=q0)
    stop = threading.Event()
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda *a: stop.set())
    # a SYNC crosses three threads here (hub, the drives' receive thread, hub again): switch the GIL every 0.5 ms
    # rather than 5 ms, and keep the collector's pauses out of the serving (set-up objects frozen, collection off)
    sys.setswitchinterval(5e-4)
    import gc
    gc.collect()
    gc.freeze()
    gc.disable()
    sim.start()
    print(f"js2-sim: {robot.name}: {sim.n} CiA 402 drives (nodes {sim.node_ids}) on {where}; "
          f"{'real-time' if args.realtime else 'lock-step'} physics; {sched}", flush=True)
    if hub is not None:
        print(f"js2-sim: PORT {hub.port}", flush=True)
        print(f"js2-sim: connect with: js2-acquire -i socketcand -c {args.channel_name} --bus-arg port={hub.port} "
              f"--trial all -o run.mcap", flush=True)
        if args.slcan_pty:
            path = hub.add_slcan_pty()
            print(f"js2-sim: SLCAN {path}", flush=True)
    try:
        stop.wait(args.duration)
    finally:
        sim.stop()
        bus.shutdown()
        if hub is not None:
            st = hub.stats()
            hub.stop()
            drops = sum(e["dropped"] for e in st["endpoints"])
            print(f"js2-sim: {sim.syncs} SYNCs served, hub relayed {st['frames']} frames, {drops} dropped", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
