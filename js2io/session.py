"""The cycle loop: enable the drives, run trials (pure per-cycle controllers), log every cycle, stop safely.

    fb(k) = SYNC k  ->  log feedback k  ->  safety checks  ->  trial.step(fb) -> command k (clamped, logged)
          ->  RPDOs (applied at SYNC k+1)  ->  SYNC k+1 ...

Safety: torque is clamped to the configured limit in the DriveGroup (the same limit is 0x6072 in each drive);
leaving the joint envelope -> quick stop; a drive fault / EMCY, a dead node (heartbeat), lost TPDOs beyond
`max_consecutive_lost`, a bus error -> `fault` + `abort` events and a safe stop; Ctrl-C / SIGTERM -> torques ramp
to zero, drives disabled. The log is closed in every case.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from js2spec.errors import Js2Error
from js2spec.log import LogWriter

from . import cia402
from .group import Command, DriveGroup, Feedback
from .trials import Trial, TrialContext, load_trials_config, make_trials


class SessionAbort(Exception):
    pass


@dataclass
class SessionResult:
    path: str
    cycles: int = 0
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    lost: list = field(default_factory=list)
    invalid_cycles: int = 0
    trials: list = field(default_factory=list)        # (name, status, summary)
    aborted: bool = False
    reason: str | None = None
    events: int = 0
    max_abs_command: list = field(default_factory=list)
    final_states: list = field(default_factory=list)

    def text(self) -> str:
        lines = [f"log: {self.path}",
                 f"cycles: {self.cycles} ({self.sim_time_s:.1f} s of arm time, {self.wall_time_s:.1f} s wall)",
                 f"lost TPDOs per drive: {self.lost} ({self.invalid_cycles} cycles with an invalid reading)"]
        for name, status, summ in self.trials:
            extra = ", ".join(f"{k} {v}" for k, v in (summ or {}).items())
            lines.append(f"  {name:<12} {status}{': ' + extra if extra else ''}")
        lines.append(f"max |commanded torque| per drive (N*m): {self.max_abs_command}")
        lines.append(f"drives at the end: {', '.join(self.final_states)}")
        if self.aborted:
            lines.append(f"ABORTED: {self.reason}")
        return "\n".join(lines)


class Session:
    def __init__(self, group: DriveGroup, writer: LogWriter, trials: list[Trial], *, progress: bool = False,
                 max_consecutive_lost: int = 10, stop_ramp_s: float = 0.3, enable_timeout_s: float = 1.0,
                 on_cycle=None, joint_state: bool = False):
        self.g = group
        self.w = writer
        self.trials = trials
        self.progress = progress
        self.max_consecutive_lost = int(max_consecutive_lost)
        self.stop_ramp_s = stop_ramp_s
        self.enable_timeout_s = enable_timeout_s
        self.stop_request: str | None = None      # set from a signal handler: "SIGINT", "SIGTERM"
        self.on_cycle = on_cycle                  # test/bench hook: called with (session, fb) every cycle
        self.joint_state = joint_state            # also write /js2/joint_state (joint side, for viewers)
        self._prev_fb = None
        self.n = group.n
        self.consec_lost = np.zeros(self.n, dtype=int)
        self.result = SessionResult(path=str(writer.path))
        self.max_cmd = np.zeros(self.n)
        self.fb: Feedback | None = None
        self.current_trial = "session"
        d = group.drives
        self.qmin = np.asarray(d.position_min, dtype=float) if d.position_min is not None else None
        self.qmax = np.asarray(d.position_max, dtype=float) if d.position_max is not None else None
        self._bar = None

    # ------------------------------------------------------------------ logging helpers
    def _event(self, kind: str, **fields) -> None:
        t = self.fb.t if self.fb is not None else 0.0
        self.w.event(t, kind, fields.pop("trial", self.current_trial), **fields)
        self.result.events += 1

    def _log_feedback(self, fb: Feedback) -> None:
        self.w.feedback(fb.cycle, fb.t, fb.motor_position, fb.torque, motor_current=fb.motor_current,
                        status=fb.status, valid=fb.valid)
        if not fb.valid.all():
            self.result.invalid_cycles += 1

    def _send(self, command: Command | None) -> None:
        sent = self.g.send(command)
        self.max_cmd = np.maximum(self.max_cmd, np.abs(sent.target_torque))
        self.w.command(self.fb.cycle, self.fb.t, sent.mode, sent.target_torque,
                       target_velocity=sent.target_velocity)

    def _sync(self) -> Feedback:
        fb = self.g.sync()
        self.fb = fb
        self._log_feedback(fb)
        if self.joint_state:
            d = self.g.drives
            prev = self._prev_fb
            dq = ((fb.motor_position - prev.motor_position) / max(fb.t - prev.t, 1e-9) if prev is not None
                  else np.zeros(self.n))
            self.w.joint_state(fb.t, d.joints, d.joint_from_motor(fb.motor_position), d.joint_velocity_from_motor(dq),
                               d.joint_torque_from_motor(fb.torque))
            self._prev_fb = fb
        if self._bar is not None and fb.cycle % 50 == 0:
            if self._bar.n + 50 >= self._bar.total:    # estimate too short: stretch rather than overflow
                self._bar.total = int(self._bar.n * 1.05) + 100
            self._bar.update(50)
        if self.on_cycle is not None:
            self.on_cycle(self, fb)
        return fb

    # ------------------------------------------------------------------ safety
    def _check(self, fb: Feedback) -> None:
        """Raise SessionAbort (after logging `fault` events) if the cycle is not safe to continue."""
        fatal = None
        for ev in self.g.poll_events():
            self._event("fault", joint=ev.joint, detail=ev.detail, value=ev.code)
            if ev.fatal and fatal is None:
                fatal = ev.detail
        self.consec_lost = np.where(fb.valid, 0, self.consec_lost + 1)
        bad = np.flatnonzero(self.consec_lost > self.max_consecutive_lost)
        if fatal is None and bad.size:
            i = int(bad[0])
            fatal = f"drive {i}: {self.consec_lost[i]} consecutive TPDOs lost (limit {self.max_consecutive_lost})"
            self._event("fault", joint=i, detail=fatal)
        if fatal is None:
            st = fb.states()
            for i, s in enumerate(st):
                if fb.valid[i] and self.g.target_state == "enabled" and s != cia402.ENABLED:
                    fatal = f"drive {i} left OPERATION ENABLED: {s} (statusword 0x{int(fb.status[i]):04X})"
                    self._event("fault", joint=i, detail=fatal)
                    break
        if fatal is not None:
            raise SessionAbort(fatal)
        if self.qmin is not None:
            qj = self.g.drives.joint_from_motor(fb.motor_position)
            out = np.flatnonzero((qj < self.qmin) | (qj > self.qmax))
            if out.size:
                j = int(out[0])
                raise SessionAbort(f"joint {self.g.drives.joints[j]} at {qj[j]:.3f} rad left the envelope "
                                   f"[{self.qmin[j]:g}, {self.qmax[j]:g}] rad: quick stop")
        if self.stop_request:
            raise SessionAbort(f"interrupted ({self.stop_request}): torques ramped to zero, drives disabled")

    # ------------------------------------------------------------------ phases
    def _enable(self) -> None:
        self.g.request("enabled")
        self._sync()     # SYNC 0: the first reading, nothing commanded yet
        for _ in range(int(self.enable_timeout_s * self.g.cycle_hz)):
            self._send(None)
            fb = self._sync()
            for ev in self.g.poll_events():
                if ev.kind == "emcy" and ev.code in (0, None):
                    continue
                self._event("fault", joint=ev.joint, detail=ev.detail, value=ev.code)
                if ev.fatal:
                    raise SessionAbort(ev.detail)
            if self.stop_request:
                raise SessionAbort(f"interrupted ({self.stop_request}) while enabling the drives")
            if self.g.all_in(cia402.ENABLED):
                return
        states = ", ".join(f"{i}: {s}" for i, s in enumerate(self.fb.states()) if s != cia402.ENABLED)
        raise SessionAbort(f"drives did not reach OPERATION ENABLED within {self.enable_timeout_s:g} s ({states}); "
                           f"check the drives (fault code 0x603F) and the bus")

    def _log_late_events(self) -> None:
        """Faults reported after the decision to stop (an EMCY behind its TPDO, a heartbeat timing out...)."""
        for ev in self.g.poll_events():
            self._event("fault", joint=ev.joint, detail=ev.detail, value=ev.code)

    def _stop(self, how: str) -> None:
        """how: 'ramp' (torques ramp to zero, then disable) or 'quick_stop' (drives brake, then disable)."""
        orig_sync = self._sync

        def _sync_logging():
            fb = orig_sync()
            self._log_late_events()
            return fb
        self._sync = _sync_logging
        try:
            if how == "ramp" and self.g.sent is not None:
                tau0 = self.g.sent.target_torque.copy()
                N = max(1, int(self.stop_ramp_s * self.g.cycle_hz))
                for k in range(1, N + 1):
                    self._send(Command(tau0 * (1.0 - k / N), mode=self.g.modes))
                    self._sync()
            elif how == "quick_stop":
                self.g.request("quick_stop")
                for _ in range(max(1, int(0.2 * self.g.cycle_hz))):
                    self._send(None)
                    self._sync()
            self.g.request("disabled")
            for _ in range(max(3, int(0.1 * self.g.cycle_hz))):
                self._send(None)
                fb = self._sync()
                if all(s in (cia402.SWITCH_ON_DISABLED, cia402.FAULT) for s, v in zip(fb.states(), fb.valid) if v):
                    break
        except Exception as e:  # the bus may be gone: nothing more we can command
            self._event("fault", detail=f"while stopping: {type(e).__name__}: {e}")
        finally:
            self._sync = orig_sync
            try:
                self._log_late_events()
            except Exception:
                pass

    # ------------------------------------------------------------------ main
    def run(self) -> SessionResult:
        import gc
        gc.collect()
        gc.freeze()    # set-up objects out of the collector's way: fewer long gen-2 pauses in the cycle loop
        t_wall = time.perf_counter()
        res = self.result
        if self.progress:
            from tqdm import tqdm
            total = int(sum(t.estimate_s() for t in self.trials) * self.g.cycle_hz)
            self._bar = tqdm(total=total, unit="cyc", desc="js2-acquire", smoothing=0.05)
        stop_how = "ramp"
        try:
            try:
                self._enable()
                for k_trial, trial in enumerate(self.trials):
                    self.current_trial = trial.name
                    if self._bar is not None:   # re-estimate what is left, so the bar never overflows
                        left = sum(t.estimate_s() for t in self.trials[k_trial:]) * 1.03 * self.g.cycle_hz
                        self._bar.total = int(self._bar.n + left)
                        self._bar.set_description(trial.name)
                    self._event("trial_start", detail=type(trial).__doc__.strip().splitlines()[0])
                    status = "aborted"
                    try:
                        while True:
                            fb = self.fb
                            self._check(fb)
                            step = trial.step(fb)
                            for ev in step.events:
                                ev = dict(ev)
                                self._event(ev.pop("kind"), **ev)
                            if step.done:
                                status = "done"
                                break
                            self._send(step.command)
                            self._sync()
                    finally:
                        res.trials.append((trial.name, status, trial.summary))
                        if status == "done":
                            self._event("trial_end")
            except SessionAbort as e:
                res.aborted, res.reason = True, str(e)
                stop_how = "ramp" if self.stop_request else "quick_stop"
                self._event("abort", detail=str(e))
            except Js2Error:
                raise
            except Exception as e:   # bus errors from python-can / canopen, and anything unexpected
                import can
                what = "bus error" if isinstance(e, (can.CanError, OSError)) else "internal error"
                res.aborted, res.reason = True, f"{what}: {type(e).__name__}: {e}"
                stop_how = "quick_stop"
                if self.fb is not None:
                    self._event("fault", detail=res.reason)
                    self._event("abort", detail=res.reason)
            self._stop(stop_how)
        finally:
            if self._bar is not None:
                if not res.aborted:
                    self._bar.total = self._bar.n
                self._bar.close()
            res.cycles = (self.fb.cycle + 1) if self.fb is not None else 0
            res.sim_time_s = self.fb.t if self.fb is not None else 0.0
            res.lost = self.g.lost.tolist()
            res.max_abs_command = [round(float(x), 5) for x in self.max_cmd]
            res.final_states = ([s if v else f"NO ANSWER (last seen {s})" for s, v in zip(self.fb.states(), self.fb.valid)]
                                if self.fb is not None else [])
            res.wall_time_s = time.perf_counter() - t_wall
            try:
                self.w.metadata("js2_acquire_summary", {
                    "cycles": res.cycles, "lost_tpdo_per_drive": res.lost, "invalid_cycles": res.invalid_cycles,
                    "aborted": res.aborted, "reason": res.reason or "",
                    "trials": ",".join(f"{n}:{s}" for n, s, _ in res.trials)})
            except Exception:
                pass
            self.w.close()
        return res


def open_log(path, robot, group: DriveGroup, trials_cfg: dict | None = None, extra: dict | None = None) -> LogWriter:
    meta = {"torque_limit": ",".join(f"{x:g}" for x in group.torque_limit),
            "torque_resolution": ",".join(f"{x:g}" for x in group.scaling.rated_torque / 1000.0),
            "acquisition": "js2io " + type(group).__name__}
    if extra:
        meta.update(extra)
    source = getattr(group, "source_detail", None) or group.source
    w = LogWriter(path, robot=robot.name, cycle_hz=group.cycle_hz, source=source, urdf_text=robot.urdf_text,
                  drives_yaml=robot.drives.to_yaml(), extra_metadata=meta)
    if trials_cfg is not None and trials_cfg.get("_path"):
        from pathlib import Path
        w.attach("trials.yaml", "application/yaml", Path(trials_cfg["_path"]).read_text())
    if getattr(robot, "eds_path", None):
        w.attach("drives.eds", "text/plain", robot.eds_path.read_text())
    return w


def run_trials(group: DriveGroup, robot, trials, path, *, trials_config=None, seed: int = 0, progress: bool = False,
               max_consecutive_lost: int = 10, extra_metadata: dict | None = None, session_hook=None) -> SessionResult:
    """Open the group, run `trials` (names or Trial objects) and write the log to `path`. Returns the summary."""
    cfg = trials_config if isinstance(trials_config, dict) else load_trials_config(
        trials_config or robot.trials_path or _default_trials())
    ctx = TrialContext(robot.drives, 1.0 / group.cycle_hz, cfg, seed=seed)
    objs = [t if isinstance(t, Trial) else None for t in trials]
    names = [t for t in trials if not isinstance(t, Trial)]
    made = iter(make_trials(names, ctx))
    trial_objs = [o if o is not None else next(made) for o in objs]
    group.open()
    w = open_log(path, robot, group, cfg, extra_metadata)
    s = Session(group, w, trial_objs, progress=progress, max_consecutive_lost=max_consecutive_lost)
    if session_hook is not None:
        session_hook(s)
    return s.run()


def _default_trials():
    from .trials import default_trials_path
    return default_trials_path()
