"""The cycle loop: enable the drives, run trials (pure per-cycle controllers), log every cycle, stop safely.

    fb(k) = SYNC k  ->  log feedback k  ->  safety checks  ->  trial.step(fb) -> command k (clamped, logged)
          ->  RPDOs (applied at SYNC k+1)  ->  SYNC k+1 ...

Safety: torque is clamped to the configured limit in the DriveGroup (the same limit is 0x6072 in each drive);
leaving the joint envelope -> quick stop; a drive fault / EMCY, a dead node (heartbeat), lost TPDOs beyond
`max_consecutive_lost`, a bus error -> `fault` + `abort` events and a safe stop; Ctrl-C / SIGTERM -> torques ramp
to zero, drives disabled. The log is closed in every case.

Stale feedback (a cycle in which some drive's TPDO did not come back in time): the trial controller is not stepped
(it never sees a stale reading, so nothing winds up or extrapolates into a command); the master holds the last
command it sent for at most `stale_hold_cycles` cycles, and only while every joint's last fresh position is farther
than `stale_guard` (fraction of the envelope span) from the envelope; otherwise, and after that, it sends zero torque
(zero velocity in CSV). The envelope check then runs on the best estimate of where a stale joint may be: its last
fresh position moved on at its last fresh velocity for as many periods as it has been stale (used to trip, never
to command).
The drives' software limits (0x607D) lie outside the envelope by a margin (`group.motor_position_limits`), so the
master's quick stop comes first. Stale cycles are counted per drive (summary, `js2_acquire_summary` metadata) and a
burst that outlasts the hold is logged as a `fault` event.

The stop path depends on nothing that can fail: every log write goes through `GuardedLog` (a failing write - full
disk, closed file, a bad value - is remembered, later writes are skipped, nothing is raised into the cycle loop),
the stop runs in a `finally`, each of its phases (ramp / quick stop, disable) is tried on its own, and the summary
reports a drive as disabled only when a fresh reading after the disable request says so. A failed log is reported
after the drives are safe.
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


NOT_CONFIRMED = "NOT CONFIRMED DISABLED (no answer)"


def one_line(e: BaseException) -> str:
    """`Type: first line of the message`, at most 200 characters: what a summary, an event or metadata carries
    (python-can puts whole tracebacks into some exception texts)."""
    text = str(e).split("Traceback (most recent call last)")[0].strip().splitlines()
    msg = " ".join(text[0].split()) if text else ""
    out = f"{type(e).__name__}: {msg}" if msg else type(e).__name__
    return out if len(out) <= 200 else out[:197] + "..."


class GuardedLog:
    """The session's only way to the log. A write that fails (OSError on a full disk, a closed writer, a value the
    encoder refuses) is remembered in `error` and every later write is skipped: the cycle loop sees a flag, never an
    exception, so neither the trial's abort nor the drives' stop can be skipped by the log."""

    def __init__(self, writer: LogWriter):
        self.writer = writer       # a LogWriter, or a RingLog in front of one (the writes then fail in its thread)
        self._error: str | None = None
        self.path = writer.path

    @property
    def error(self) -> str | None:
        return self._error if self._error is not None else getattr(self.writer, "error", None)

    @error.setter
    def error(self, value: str | None) -> None:
        self._error = value

    def __getattr__(self, name):
        fn = getattr(self.writer, name)

        def guarded(*a, **kw):
            if self.error is not None:
                return None
            try:
                return fn(*a, **kw)
            except Exception as e:   # noqa: BLE001 - any failure of the log must not reach the stop path
                self.error = f"log write failed ({name}): {one_line(e)}"
                return None
        return guarded

    def close(self) -> None:
        """Close the file even after a failed write (the mcap footer may then be missing: the reader recovers the
        complete chunks, `js2-repair` rewrites it)."""
        w = self.writer
        if getattr(w, "closed", False):
            return
        try:
            if self.error is None:
                w.close()
                return
        except Exception as e:   # noqa: BLE001
            self.error = f"log could not be closed: {one_line(e)}"
        w.abandon()                  # LogWriter, or RingLog (stops its thread first)


@dataclass
class SessionResult:
    path: str
    cycles: int = 0
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    lost: list = field(default_factory=list)
    invalid_cycles: int = 0
    stale: list = field(default_factory=list)          # stale cycles per drive (its TPDO not back in time)
    longest_stale: list = field(default_factory=list)  # longest run of consecutive stale cycles per drive
    stale_held: int = 0                                # stale cycles that repeated the last command
    stale_zeroed: int = 0                              # stale cycles that sent zero torque instead
    missed: int | None = None                          # real time: SYNC deadlines overrun by > 1 period (skipped)
    trials: list = field(default_factory=list)        # (name, status, summary)
    aborted: bool = False
    reason: str | None = None
    events: int = 0
    max_abs_command: list = field(default_factory=list)
    final_states: list = field(default_factory=list)
    stop_errors: list = field(default_factory=list)   # what failed while stopping (one line each)
    warnings: list = field(default_factory=list)      # what the user should know although nothing stopped
    log_error: str | None = None
    debug_path: str | None = None          # full traceback of an unexpected error, if one was written

    def text(self) -> str:
        lines = [f"log: {self.path}",
                 f"cycles: {self.cycles} ({self.sim_time_s:.1f} s of arm time, {self.wall_time_s:.1f} s wall)",
                 f"lost TPDOs per drive: {self.lost} ({self.invalid_cycles} cycles with an invalid reading)",
                 f"stale cycles per drive: {self.stale} (longest run {self.longest_stale}; in trials "
                 f"{self.stale_held} held the last command, {self.stale_zeroed} sent zero torque)"]
        if self.missed is not None:
            lines.append(f"real time: {self.missed} SYNC deadlines missed (overrun by more than a period, skipped)")
        for name, status, summ in self.trials:
            extra = ", ".join(f"{k} {v}" for k, v in (summ or {}).items())
            lines.append(f"  {name:<12} {status}{': ' + extra if extra else ''}")
        lines.append(f"max |commanded torque| per drive (N*m): {self.max_abs_command}")
        lines.append(f"drives at the end: {', '.join(self.final_states)}")
        lines += [f"WARNING: {w}" for w in self.warnings]
        if self.aborted:
            lines.append(f"ABORTED: {self.reason}")
        if self.log_error:
            lines.append(f"LOG INCOMPLETE: {self.log_error}; the drives were stopped regardless. Free space or choose "
                         f"another -o; `js2-repair {self.path}` recovers what was written")
        if self.debug_path:
            lines.append(f"details for a bug report: {self.debug_path}")
        return "\n".join(lines)


class Session:
    def __init__(self, group: DriveGroup, writer: LogWriter, trials: list[Trial], *, progress: bool = False,
                 max_consecutive_lost: int = 10, stop_ramp_s: float = 0.3, enable_timeout_s: float = 1.0,
                 on_cycle=None, joint_state: bool = False, stale_hold_cycles: int = 2, stale_guard: float = 0.05,
                 threaded_log: bool | None = None):
        """threaded_log: hand samples to a writer thread through a preallocated ring (`js2io.logring.RingLog`);
        default: when the group runs in real time."""
        self.g = group
        if threaded_log is None:
            threaded_log = bool(getattr(group, "realtime", False))
        self.threaded_log = threaded_log
        if not isinstance(writer, GuardedLog) and threaded_log:
            from .logring import RingLog
            writer = RingLog(writer, describe=one_line)
        self.w = writer if isinstance(writer, GuardedLog) else GuardedLog(writer)
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
        self.consec_lost = np.zeros(self.n, dtype=int)     # current run of stale cycles per drive
        self.stale = np.zeros(self.n, dtype=int)
        self.longest_stale = np.zeros(self.n, dtype=int)
        self.stale_hold_cycles = int(stale_hold_cycles)
        self.stale_guard = float(stale_guard)
        self._q_fresh = None                               # motor rad, last fresh reading per drive
        self._v_fresh = np.zeros(self.n)                   # motor rad/s between the last two fresh readings
        self._t_fresh = np.zeros(self.n)                   # s, time of the last fresh reading
        self._zero_logged = False
        self.result = SessionResult(path=str(writer.path))
        self.max_cmd = np.zeros(self.n)
        self.fb: Feedback | None = None
        self.current_trial = "session"
        d = group.drives
        self.qmin = np.asarray(d.position_min, dtype=float) if d.position_min is not None else None
        self.qmax = np.asarray(d.position_max, dtype=float) if d.position_max is not None else None
        self._bar = None
        self.confirmed = np.zeros(self.n, dtype=bool)      # drive answered with a disabled state after that
        self.at_limit = np.zeros(self.n, dtype=int)        # this trial's cycles commanded at the torque limit
        self.active = np.zeros(self.n, dtype=int)          # ... and with any torque commanded

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
        tau = np.abs(sent.target_torque)
        self.max_cmd = np.maximum(self.max_cmd, tau)
        self.active += tau > 0
        self.at_limit += tau >= self.g.torque_limit * (1 - 1e-6)
        self.w.command(self.fb.cycle, self.fb.t, sent.mode, sent.target_torque,
                       target_velocity=sent.target_velocity)

    def _sync(self) -> Feedback:
        fb = self.g.sync()
        self.fb = fb
        self._log_feedback(fb)
        self._track_fresh(fb)
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
    def _track_fresh(self, fb: Feedback) -> None:
        """Per drive: stale-cycle counts and runs; last fresh position, velocity and time (for the envelope check)."""
        ok = np.asarray(fb.valid, dtype=bool)
        self.consec_lost = np.where(ok, 0, self.consec_lost + 1)
        self.stale += ~ok
        np.maximum(self.longest_stale, self.consec_lost, out=self.longest_stale)
        q = fb.motor_position
        if self._q_fresh is None:
            if ok.all():
                self._q_fresh, self._t_fresh[:] = q.copy(), fb.t
            return
        if ok.any():
            gap = np.maximum(fb.t - self._t_fresh, 1e-9)
            self._v_fresh = np.where(ok, (q - self._q_fresh) / gap, self._v_fresh)
            self._q_fresh = np.where(ok, q, self._q_fresh)
            self._t_fresh = np.where(ok, fb.t, self._t_fresh)

    def motor_position_estimate(self, fb: Feedback) -> np.ndarray:
        """Where each motor may be now: the fresh reading, or for a stale drive its last fresh position moved on at its
        last fresh velocity for as many periods as its feedback has been stale. For the envelope check only, never
        for a command. (Counted in periods, not seconds since the reading: a stall of the master itself -- no SYNC
        sent -- is not the drive's staleness; the next fresh reading shows where the arm went meanwhile.)"""
        if self._q_fresh is None or fb.valid.all():
            return fb.motor_position
        age = self.consec_lost * self.g.dt
        return np.where(fb.valid, fb.motor_position, self._q_fresh + self._v_fresh * age)

    def _stale_command(self) -> Command:
        """The command of a cycle with stale feedback: the last one sent, for at most `stale_hold_cycles` and only
        with every joint clear of the envelope by `stale_guard` of its span; else zero torque (CSV: zero velocity)."""
        run = int(self.consec_lost.max())
        sent = self.g.sent
        if sent is not None and run <= self.stale_hold_cycles and self._clear_of_envelope():
            self.result.stale_held += 1
            return Command(sent.target_torque.copy(), mode=self.g.modes.copy(),
                           target_velocity=None if sent.target_velocity is None else sent.target_velocity.copy())
        self.result.stale_zeroed += 1
        if not self._zero_logged:     # once per burst
            self._zero_logged = True
            stale = np.flatnonzero(self.consec_lost)
            self._event("fault", joint=int(stale[0]) if stale.size else None,
                        detail=f"stale feedback of drive(s) {stale.tolist()} for {run} cycles: zero torque until "
                               f"fresh readings return")
        z = np.zeros(self.n)
        return Command(z, mode=self.g.modes.copy(),
                       target_velocity=z.copy() if np.any(self.g.modes == cia402.MODE_CSV) else None)

    def _clear_of_envelope(self) -> bool:
        if self.qmin is None or self._q_fresh is None:
            return self.qmin is None
        qj = self.g.drives.joint_from_motor(self._q_fresh)
        guard = self.stale_guard * (self.qmax - self.qmin)
        return bool(np.all((qj > self.qmin + guard) & (qj < self.qmax - guard)))

    def _check(self, fb: Feedback) -> None:
        """Raise SessionAbort (after logging `fault` events) if the cycle is not safe to continue."""
        fatal = None
        for ev in self.g.poll_events():
            self._event("fault", joint=ev.joint, detail=ev.detail, value=ev.code)
            if ev.fatal and fatal is None:
                fatal = ev.detail
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
        if self.w.error is not None:
            raise SessionAbort(self.w.error)
        if self.qmin is not None:
            qj = self.g.drives.joint_from_motor(self.motor_position_estimate(fb))
            out = np.flatnonzero((qj < self.qmin) | (qj > self.qmax))
            if out.size:
                j = int(out[0])
                stale = np.flatnonzero(~np.asarray(fb.valid, dtype=bool))
                how = (f"predicted at {qj[j]:.3f} rad (feedback of drive(s) {stale.tolist()} stale for "
                       f"{int(self.consec_lost.max())} cycles)" if stale.size else f"at {qj[j]:.3f} rad")
                raise SessionAbort(f"joint {self.g.drives.joints[j]} {how} left the envelope "
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
        """how: 'ramp' (torques ramp to zero, then disable) or 'quick_stop' (drives brake, then disable).

        Never raises. Each phase is tried on its own: a bus that fails during the ramp still gets the disable
        request; log writes cannot fail here (GuardedLog). `self.confirmed[i]` is set only by a fresh (valid)
        reading of drive i, after the disable request, that shows it no longer enabled."""
        def step(command):
            self._send(command)
            fb = self._sync()
            self._log_late_events()
            return fb

        try:
            if how == "ramp" and self.g.sent is not None:
                tau0 = self.g.sent.target_torque.copy()
                N = max(1, int(self.stop_ramp_s * self.g.cycle_hz))
                for k in range(1, N + 1):
                    step(Command(tau0 * (1.0 - k / N), mode=self.g.modes))
            elif how == "quick_stop":
                self.g.request("quick_stop")
                for _ in range(max(1, int(0.2 * self.g.cycle_hz))):
                    step(None)
        except Exception as e:   # noqa: BLE001 - the bus may be gone; still ask for the disable below
            self._stop_error(f"while ramping down ({how}): {one_line(e)}")
        try:
            self.g.request("disabled")
            off = (cia402.SWITCH_ON_DISABLED, cia402.FAULT, cia402.READY, cia402.SWITCHED_ON, cia402.NOT_READY)
            for _ in range(max(5, int(0.1 * self.g.cycle_hz))):
                fb = step(None)    # valid = this cycle's TPDO arrived: a stale copy never confirms anything
                self.confirmed |= np.asarray(fb.valid, dtype=bool) & np.array([s in off for s in fb.states()])
                if self.confirmed.all():
                    break
        except Exception as e:   # noqa: BLE001
            self._stop_error(f"while disabling the drives: {one_line(e)}")

    SATURATION_WARN = 0.25     # fraction of a drive's active cycles at the torque limit that earns a warning

    def _warn_saturation(self, trial: str) -> None:
        """A drive held at the torque limit for much of a trial: the trial asked for more than the limit allows
        (breakaways not reached, strokes not followed). Said once per trial and drive; counters reset."""
        frac = self.at_limit / np.maximum(self.active, 1)
        for i in np.flatnonzero((frac > self.SATURATION_WARN) & (self.active > 0.2 * self.g.cycle_hz)):
            self.result.warnings.append(
                f"drive {i} ({self.g.drives.joints[i]}) was commanded at its torque limit "
                f"{self.g.torque_limit[i]:g} N*m in {100 * frac[i]:.0f} % of its active cycles during '{trial}': "
                f"results of that trial may be missing or biased; raise torque_limit in drives.yaml (within the "
                f"drive's rating) or ask less of the trial")
        self.at_limit[:] = 0
        self.active[:] = 0

    def _stop_error(self, detail: str) -> None:
        self.result.stop_errors.append(detail)
        try:
            self._event("fault", detail=detail)
        except Exception:   # noqa: BLE001 - self.fb may be missing; the detail is in the result already
            pass

    def _final_states(self) -> list[str]:
        """What the summary may claim: the state a drive confirmed after the disable request, or that it did not."""
        if self.fb is None:
            return [NOT_CONFIRMED] * self.n
        return [s if ok else NOT_CONFIRMED for s, ok in zip(self.fb.states(), self.confirmed)]

    def _write_debug(self, exc: BaseException) -> str | None:
        """The full traceback of an unexpected error, beside the log (best effort: the disk may be full)."""
        import traceback
        path = f"{self.result.path}.error.txt"
        try:
            with open(path, "w") as f:
                f.write("".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
            return path
        except OSError:
            return None

    # ------------------------------------------------------------------ main
    def run(self) -> SessionResult:
        """Garbage collection is off for the session (set-up objects frozen first; the cycle makes no reference
        cycles worth a pause); in real time the interpreter also switches threads every 0.5 ms instead of 5 ms, so
        the cycle thread waits at most that for the GIL (the log writer thread is the other taker)."""
        import gc
        import sys
        gc.collect()
        gc.freeze()
        gc_was = gc.isenabled()
        gc.disable()
        switch = sys.getswitchinterval()
        if getattr(self.g, "realtime", False):
            sys.setswitchinterval(5e-4)
        try:
            return self._run()
        finally:
            sys.setswitchinterval(switch)
            if gc_was:
                gc.enable()

    def _run(self) -> SessionResult:
        t_wall = time.perf_counter()
        res = self.result
        stop_how = "quick_stop"      # anything that escapes below (even BaseException) ends in a quick stop
        try:
            if self.progress:
                from tqdm import tqdm
                total = int(sum(t.estimate_s() for t in self.trials) * self.g.cycle_hz)
                # disable=None: no bar when stderr is not a terminal (a CI log, a file): no carriage-return spam
                self._bar = tqdm(total=total, unit="cyc", desc="js2-acquire", smoothing=0.05, disable=None)
                if self._bar.disable:
                    self._bar = None
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
                        if fb.valid.all():       # the trial only ever sees fresh readings
                            self._zero_logged = False
                            step = trial.step(fb)
                            for ev in step.events:
                                ev = dict(ev)
                                self._event(ev.pop("kind"), **ev)
                            if step.done:
                                status = "done"
                                break
                            command = step.command
                        else:
                            command = self._stale_command()
                        self._send(command)
                        self._sync()
                finally:
                    res.trials.append((trial.name, status, trial.summary))
                    self._warn_saturation(trial.name)
                    if status == "done":
                        self._event("trial_end")
            stop_how = "ramp"
        except SessionAbort as e:
            res.aborted, res.reason = True, str(e)
            stop_how = "ramp" if self.stop_request else "quick_stop"
        except Js2Error as e:         # a configuration problem met mid-session: stop first, then report it (exit 2)
            res.aborted, res.reason = True, str(e)
            raise
        except Exception as e:   # noqa: BLE001 - bus errors from python-can / canopen, and anything unexpected
            import can
            what = "bus error" if isinstance(e, (can.CanError, OSError)) else "internal error"
            res.aborted, res.reason = True, f"{what}: {one_line(e)}"
            res.debug_path = self._write_debug(e)
        except BaseException as e:    # KeyboardInterrupt without a handler, SystemExit: stop, then let it go on
            res.aborted, res.reason = True, f"interrupted: {one_line(e)}"
            raise
        finally:
            if res.aborted:
                self._event("abort", detail=res.reason)     # GuardedLog: cannot raise
            self._stop(stop_how)                              # never raises; nothing above can skip it
            self._finish(t_wall)
        return res

    def _finish(self, t_wall: float) -> None:
        """Summary and log close, after the drives are safe. Never raises."""
        res = self.result
        try:
            if self._bar is not None:
                if not res.aborted:
                    self._bar.total = self._bar.n
                self._bar.close()
        except Exception:   # noqa: BLE001 - a broken terminal must not hide the summary
            pass
        res.cycles = (self.fb.cycle + 1) if self.fb is not None else 0
        res.sim_time_s = self.fb.t if self.fb is not None else 0.0
        res.lost = self.g.lost.tolist()
        res.stale = self.stale.tolist()
        if getattr(self.g, "realtime", False):
            res.missed = int(getattr(self.g, "missed", 0))
        res.longest_stale = self.longest_stale.tolist()
        res.max_abs_command = [round(float(x), 5) for x in self.max_cmd]
        res.final_states = self._final_states()
        res.wall_time_s = time.perf_counter() - t_wall
        self.w.metadata("js2_acquire_summary", {
            "cycles": res.cycles, "lost_tpdo_per_drive": res.lost, "invalid_cycles": res.invalid_cycles,
            "stale_cycles_per_drive": ",".join(map(str, res.stale)),
            "longest_stale_run_per_drive": ",".join(map(str, res.longest_stale)),
            "stale_commands_held": res.stale_held, "stale_commands_zero": res.stale_zeroed,
            "missed_sync_deadlines": "" if res.missed is None else res.missed,
            "aborted": res.aborted, "reason": res.reason or "",
            "drives_disabled_confirmed": ",".join(str(bool(c)).lower() for c in self.confirmed),
            "warnings": " | ".join(res.warnings),
            "trials": ",".join(f"{n}:{s}" for n, s, _ in res.trials)})
        self.w.close()
        res.log_error = self.w.error
        if res.log_error and not res.aborted:
            # the trials ran to their end, but a writer thread behind them met the error after the last cycle (a
            # group faster than real time fills its ring): the recording is incomplete all the same, so the run
            # failed (js2-acquire exits 1), as when the error stops it mid-trial
            res.aborted, res.reason = True, res.log_error


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
