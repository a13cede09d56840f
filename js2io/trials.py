"""The paper's trials as pure per-cycle controllers: feedback (SI) -> command (SI) + events.

Every trial runs in cyclic synchronous torque mode (10): the host closes the loops it needs (a PID on the motor
positions with velocity feed-forward) so the torque that reaches the drive is known exactly and logged. Internally a
trial is a generator that yields one reference per cycle; `Trial.step(fb)` turns it into a `Command`.

Trials (configured in configs/<robot>/trials.yaml):
  static        breakaway ramps per axis, several poses, both directions (eq. 2-4)
  velocity      constant-velocity runs per axis, several speeds, both directions, steady segments marked (eq. 5)
  acceleration  all axes together, constant acceleration strokes (the simultaneous test)
  excitation    finite Fourier series within joint, speed and torque limits
  validation    another finite Fourier series (different seed/period), for checking a model
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from js2spec.errors import ConfigError

from .cia402 import MODE_CSV, MODE_CST
from .group import Command, Feedback

TRIAL_NAMES = ("static", "velocity", "acceleration", "excitation", "validation")


# ---------------------------------------------------------------------------------------------------- config
def default_trials_path() -> Path:
    return Path(__file__).resolve().parents[1] / "configs" / "js2" / "trials.yaml"


def load_trials_config(path) -> dict:
    from js2spec.files import load_yaml
    path = Path(path)
    if not path.is_file() and not path.is_dir():
        raise ConfigError(path, None, "trials file not found; pass --config FILE or add trials.yaml to the robot folder")
    cfg = load_yaml(path, "trials file")
    if not isinstance(cfg, dict):
        raise ConfigError(path, None, "must be a mapping with sections control, static, velocity, ...")
    cfg["_path"] = str(path)
    check_keys(cfg)
    return cfg


KNOWN_KEYS = {
    None: {"margin", "control", "static", "velocity", "acceleration", "excitation", "validation", "_path"},
    "control": {"kp", "kd", "ki", "velocity_filter_hz", "max_acceleration"},
    "static": {"poses", "axes", "directions", "ramp_rate", "max_ramp", "threshold_counts", "settle_s", "backoff_s",
               "rest_s", "rest_timeout_s", "attempts"},
    "velocity": {"pose", "axes", "max_speed", "speed_fractions", "acceleration", "steady_s", "settle_s", "mode"},
    "acceleration": {"center", "amplitude", "durations", "strokes_per_duration", "speed_fraction", "pause_s", "seed"},
    "excitation": {"center", "period_s", "harmonics", "periods", "amplitude", "speed_fraction", "fade_s", "seed"},
}
KNOWN_KEYS["validation"] = KNOWN_KEYS["excitation"]


def check_keys(cfg: dict) -> None:
    """Refuse unknown keys: a misspelt key would otherwise silently fall back to a default."""
    path = cfg.get("_path")
    for section, known in KNOWN_KEYS.items():
        d = cfg if section is None else cfg.get(section)
        if d is None:
            continue
        if not isinstance(d, dict):
            raise ConfigError(path, section, "must be a mapping")
        bad = sorted(set(d) - known)
        if bad:
            where = bad[0] if section is None else f"{section}.{bad[0]}"
            raise ConfigError(path, where, f"unknown key; known here: {', '.join(sorted(known - {'_path'}))}")


def _vec(cfg: dict, key: str, n: int, path, default=None) -> np.ndarray:
    v = cfg.get(key, default)
    if v is None:
        raise ConfigError(path, key, "missing")
    a = np.asarray(v, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ConfigError(path, key, f"needs {n} values (one per drive/joint), got {a.tolist()}")
    return a


@dataclass
class TrialContext:
    """What a trial knows about the arm (all from drives.yaml + trials.yaml; nothing measured)."""
    drives: object
    dt: float
    cfg: dict
    seed: int = 0
    margin: float = 0.1

    def __post_init__(self):
        d = self.drives
        self.n = d.n
        self.K = np.asarray(d.gear_ratio_matrix, dtype=float)
        self.Kinv = np.linalg.inv(self.K)
        self.offset = np.asarray(d.joint_offset, dtype=float)
        self.path = self.cfg.get("_path")
        inf = np.full(self.n, np.inf)
        self.qmin = np.asarray(d.position_min, dtype=float) if d.position_min is not None else -inf
        self.qmax = np.asarray(d.position_max, dtype=float) if d.position_max is not None else inf
        self.vlim = (np.asarray(d.velocity_limit, dtype=float) if d.velocity_limit is not None
                     else np.full(self.n, 100.0))
        lim = d.torque_limit if d.torque_limit is not None else d.rated_torque
        self.tau_limit = np.asarray(lim, dtype=float)
        self.margin = float(self.cfg.get("margin", self.margin))
        c = self.cfg.get("control", {}) or {}
        self.kp = _vec(c, "kp", self.n, self.path)
        self.kd = _vec(c, "kd", self.n, self.path)
        self.ki = _vec(c, "ki", self.n, self.path, default=0.0)
        self.vel_filter_hz = float(c.get("velocity_filter_hz", 40.0))
        self.acc_max = _vec(c, "max_acceleration", self.n, self.path, default=1000.0)   # motor rad/s^2

    def motor(self, q_joint) -> np.ndarray:
        return self.Kinv @ (np.asarray(q_joint, dtype=float) - self.offset)

    def joint(self, q_motor) -> np.ndarray:
        return self.K @ np.asarray(q_motor, dtype=float) + self.offset

    def inner_lo_hi(self):
        return self.qmin + self.margin, self.qmax - self.margin

    def check_pose(self, q, key: str) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n,):
            raise ConfigError(self.path, key, f"a pose needs {self.n} joint angles, got {q.tolist()}")
        lo, hi = self.inner_lo_hi()
        if np.any(q < lo) or np.any(q > hi):
            raise ConfigError(self.path, key, f"pose {q.tolist()} is outside the joint envelope minus the margin "
                              f"{self.margin} rad ([{lo.round(3).tolist()}, {hi.round(3).tolist()}])")
        return q

    def axis_range(self, m_pose: np.ndarray, i: int) -> tuple[float, float]:
        """Range of motor i (others fixed at m_pose) keeping every joint inside the envelope minus the margin."""
        lo, hi = self.inner_lo_hi()
        q0 = self.joint(m_pose)
        a, b = -np.inf, np.inf
        for j in range(self.n):
            k = self.K[j, i]
            if abs(k) < 1e-15:
                continue
            x1, x2 = (lo[j] - q0[j]) / k, (hi[j] - q0[j]) / k
            a, b = max(a, min(x1, x2)), min(b, max(x1, x2))
        return m_pose[i] + a, m_pose[i] + b


# ---------------------------------------------------------------------------------------------------- control
@dataclass
class Ref:
    q: np.ndarray                      # motor position reference (rad)
    dq: np.ndarray                     # motor velocity reference (rad/s)
    open_loop: dict = field(default_factory=dict)   # drive -> torque (N*m): bypass the tracker on that axis
    csv: tuple = ()                    # drives run by their own velocity loop (CSV, mode 9) on this cycle


class Tracker:
    """PID on motor positions with velocity feed-forward; per-axis open-loop override with bumpless return."""

    def __init__(self, ctx: TrialContext):
        self.ctx = ctx
        self.alpha = 1.0 - math.exp(-2 * math.pi * ctx.vel_filter_hz * ctx.dt)
        self.q = None
        self.v = np.zeros(ctx.n)
        self.integ = np.zeros(ctx.n)
        self.last_tau = np.zeros(ctx.n)
        self.was_open: set[int] = set()

    def observe(self, fb: Feedback) -> None:
        """Velocity from encoder differences; a lost (stale) reading is skipped, the next valid one spans the gap,
        and meanwhile the position is extrapolated (a stale position against a moving reference would kick)."""
        q = fb.motor_position
        if self.q is None:
            self.q = q.copy()
            self.q_now = q.copy()
            self._k = np.full(self.ctx.n, fb.cycle)
            return
        ok = np.asarray(fb.valid, dtype=bool)
        gap = np.maximum(fb.cycle - self._k, 1) * self.ctx.dt
        if ok.any():
            v_raw = (q - self.q) / gap
            self.v = np.where(ok, self.v + self.alpha * (v_raw - self.v), self.v)
            self.q = np.where(ok, q, self.q)
            self._k = np.where(ok, fb.cycle, self._k)
        self.q_now = np.where(ok, self.q, self.q + self.v * gap)

    def command(self, ref: Ref) -> np.ndarray:
        c = self.ctx
        e = ref.q - self.q_now
        tau_pd = c.kp * e + c.kd * (ref.dq - self.v)
        for i in self.was_open - set(ref.open_loop):
            self.integ[i] = self.last_tau[i] - tau_pd[i]   # bumpless: continue from the open-loop torque
        tau = tau_pd + self.integ
        sat = np.abs(tau) >= 0.95 * c.tau_limit
        self.integ += np.where(sat & (np.sign(tau) == np.sign(e)), 0.0, c.ki * e * c.dt)
        self.integ = np.clip(self.integ, -c.tau_limit, c.tau_limit)
        tau = tau_pd + self.integ
        for i, t in ref.open_loop.items():
            tau[i] = t
        self.was_open = set(ref.open_loop)
        tau = np.clip(tau, -c.tau_limit, c.tau_limit)
        self.last_tau = tau
        return tau


# ---------------------------------------------------------------------------------------------------- trials
@dataclass
class TrialStep:
    command: Command
    events: list[dict]
    done: bool = False


class Trial:
    """Base: subclasses implement `plan()` (a generator: `fb = yield Ref(...)`) and `estimate_s()`."""
    name = "trial"

    def __init__(self, ctx: TrialContext):
        self.ctx = ctx
        self.cfg = ctx.cfg.get(self.name, {}) or {}
        self.path = ctx.path
        self.tracker = Tracker(ctx)
        self._gen = None
        self._events: list[dict] = []
        self.fb: Feedback | None = None
        self.summary: dict = {}
        self.hold_q: np.ndarray | None = None

    # -- public per-cycle interface
    def step(self, fb: Feedback) -> TrialStep:
        self.fb = fb
        self.tracker.observe(fb)
        try:
            if self._gen is None:
                self.hold_q = fb.motor_position.copy()
                self._gen = self.plan()
                ref = next(self._gen)
            else:
                ref = self._gen.send(fb)
        except StopIteration:
            ev, self._events = self._events, []
            return TrialStep(Command(self.tracker.command(Ref(self.hold_q, np.zeros(self.ctx.n))),
                                     mode=np.full(self.ctx.n, MODE_CST)), ev, done=True)
        self.hold_q = ref.q
        mode = np.full(self.ctx.n, MODE_CST)
        vel = None
        if ref.csv:
            # cascaded: host position loop -> drive velocity loop; the torque is the drive's (measured, not commanded)
            vel = np.zeros(self.ctx.n)
            opened = dict(ref.open_loop)
            for i in ref.csv:
                mode[i] = MODE_CSV
                vel[i] = ref.dq[i] + self.csv_kpos * (ref.q[i] - self.tracker.q_now[i])
                opened[i] = float(fb.torque[i])
            ref = Ref(ref.q, ref.dq, opened)
        tau = self.tracker.command(ref)
        if vel is not None:
            tau[mode == MODE_CSV] = 0.0
        ev, self._events = self._events, []
        return TrialStep(Command(tau, mode=mode, target_velocity=vel), ev)

    csv_kpos = 20.0   # 1/s: host position correction added to the CSV velocity target

    def with_csv(self, gen, axes: tuple):
        """Run a reference generator with `axes` in CSV (mode 9)."""
        try:
            ref = next(gen)
            while True:
                ref.csv = tuple(axes)
                fb = yield ref
                ref = gen.send(fb)
        except StopIteration:
            return

    def emit(self, kind: str, **fields) -> None:
        self._events.append(dict(kind=kind, **fields))

    def plan(self):  # pragma: no cover - abstract
        raise NotImplementedError
        yield

    def estimate_s(self) -> float:
        return 10.0

    # -- building blocks (generators)
    def n_cycles(self, seconds: float) -> int:
        return max(1, int(round(seconds / self.ctx.dt)))

    def hold(self, q, seconds: float):
        q = np.asarray(q, dtype=float)
        z = np.zeros(self.ctx.n)
        for _ in range(self.n_cycles(seconds)):
            yield Ref(q, z)

    def move(self, q_to, speed_fraction: float = 0.25, min_s: float = 0.5):
        """Quintic move in motor space from the current reference to q_to (motor rad)."""
        q0 = self.hold_q.copy() if self.hold_q is not None else self.fb.motor_position.copy()
        q1 = np.asarray(q_to, dtype=float)
        d = q1 - q0
        vmax = speed_fraction * self.ctx.vlim
        amax = 0.5 * self.ctx.acc_max
        T = max(min_s, float(np.max(1.875 * np.abs(d) / vmax)), float(np.max(np.sqrt(5.77 * np.abs(d) / amax))))
        N = self.n_cycles(T)
        for k in range(1, N + 1):
            s = k / N
            p = 10 * s**3 - 15 * s**4 + 6 * s**5
            dp = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
            yield Ref(q0 + d * p, d * dp)

    def move_time(self, d) -> float:
        d = np.abs(np.asarray(d, dtype=float))
        return max(0.5, float(np.max(1.875 * d / (0.25 * self.ctx.vlim))),
                   float(np.max(np.sqrt(5.77 * d / (0.5 * self.ctx.acc_max)))))


class StaticTrial(Trial):
    """Breakaway ramps: hold a pose, ramp one motor's torque (open loop, others held) from the holding torque until
    the encoder first moves; `breakaway` = torque applied during the interval in which it moved; back off."""
    name = "static"

    def __init__(self, ctx):
        super().__init__(ctx)
        c, n = self.cfg, ctx.n
        self.poses = [ctx.check_pose(p, f"static.poses[{k}]") for k, p in enumerate(c.get("poses", [[0.0] * n]))]
        self.axes = [int(a) for a in c.get("axes", range(n))]
        self.rate = _vec(c, "ramp_rate", n, self.path)          # N*m/s
        self.max_ramp = _vec(c, "max_ramp", n, self.path, default=list(ctx.tau_limit))
        self.threshold = int(c.get("threshold_counts", 2))
        self.settle_s = float(c.get("settle_s", 0.4))
        self.backoff_s = float(c.get("backoff_s", 0.3))
        self.directions = [int(x) for x in c.get("directions", [1, -1])]
        self.rest_s = float(c.get("rest_s", 0.1))
        self.rest_timeout_s = float(c.get("rest_timeout_s", 2.0))
        self.attempts = int(c.get("attempts", 3))

    def estimate_s(self) -> float:
        return len(self.poses) * (1.5 + len(self.axes) * len(self.directions) *
                                  (self.settle_s + self.rest_s + self.backoff_s + 0.9))

    def plan(self):
        ctx = self.ctx
        n_break = 0
        for pose in self.poses:
            m_pose = ctx.motor(pose)
            yield from self.move(m_pose)
            for i in self.axes:
                for direction in self.directions:
                    z = np.zeros(ctx.n)
                    for attempt in range(self.attempts):
                        yield from self.hold(m_pose, self.settle_s)
                        # at rest under the PID (no count change for rest_s) ...
                        c_last, still, waited = int(self.fb.counts[i]), 0, 0
                        while still < self.n_cycles(self.rest_s) and waited < self.n_cycles(self.rest_timeout_s):
                            fb = yield Ref(m_pose, z)
                            waited += 1
                            still = still + 1 if int(fb.counts[i]) == c_last else 0
                            c_last = int(fb.counts[i])
                        # ... and still at rest under the constant holding torque alone (inside the friction cone),
                        # otherwise the ramp would start at a breakaway edge: hold again and retry
                        tau0 = float(self.tracker.last_tau[i])
                        c0 = int(self.fb.counts[i])
                        at_rest = True
                        for _ in range(self.n_cycles(self.rest_s)):
                            fb = yield Ref(m_pose, z, {i: tau0})
                            if int(fb.counts[i]) != c0:
                                at_rest = False
                                break
                        if at_rest:
                            break
                        self.tracker.last_tau[i] = tau0
                    fb = self.fb
                    c0 = int(fb.counts[i])
                    start_cycle = fb.cycle
                    hist: dict[int, float] = {}       # cycle -> torque commanded in that cycle
                    self.emit("segment_start", joint=i, direction=direction, pose=list(pose))
                    k = 0
                    first_move_cycle = None
                    result = None
                    while True:
                        k += 1
                        tau = tau0 + direction * self.rate[i] * k * ctx.dt
                        if abs(tau - tau0) > self.max_ramp[i] or abs(tau) >= ctx.tau_limit[i]:
                            result = ("none", f"no movement up to {tau - direction * self.rate[i] * ctx.dt:.5f} N*m "
                                      f"(ramp limit)")
                            break
                        fb = yield Ref(m_pose, np.zeros(ctx.n), {i: tau})
                        hist[fb.cycle - 1] = tau
                        if not fb.valid[i]:
                            continue
                        moved = direction * (int(fb.counts[i]) - c0)     # in the direction of the ramp
                        if moved <= -self.threshold:
                            result = ("none", f"moved against the ramp ({moved} counts): breakaway not measured")
                            break
                        if moved >= 1 and first_move_cycle is None:
                            first_move_cycle = fb.cycle
                        elif moved <= 0:
                            first_move_cycle = None
                        if moved >= self.threshold:
                            # feedback of cycle f first showed movement: it happened between SYNC f-1 and f,
                            # under the command logged with cycle f-2 (applied at SYNC f-1)
                            c_cmd = first_move_cycle - 2
                            value = hist.get(c_cmd, tau0)   # before the ramp's first command: the holding torque
                            result = ("ok", value)
                            break
                    if result[0] == "ok":
                        n_break += 1
                        self.emit("breakaway", joint=i, direction=direction, pose=list(pose), value=result[1],
                                  detail=f"first encoder movement (1 count, confirmed at {self.threshold} counts); "
                                         f"value = torque applied when it moved (command of cycle "
                                         f"{first_move_cycle - 2}); ramp {self.rate[i]:g} N*m/s from "
                                         f"{tau0:.5f} N*m (cycle {start_cycle})"
                                         + ("" if at_rest else "; WARNING: axis was not at rest at the start"))
                        self.emit("segment_end", joint=i, direction=direction, pose=list(pose))
                    else:
                        self.emit("segment_end", joint=i, direction=direction, pose=list(pose), detail=result[1])
                    # back off: torque back to the holding torque, brake, return to the pose
                    self.tracker.last_tau[i] = tau0
                    here = self.hold_q.copy()
                    here[i] = self.fb.motor_position[i]
                    self.hold_q = here
                    yield from self.hold(here, self.backoff_s / 2)
                    yield from self.move(m_pose, min_s=self.backoff_s / 2)
        self.summary = {"breakaways": n_break, "ramps": len(self.poses) * len(self.axes) * len(self.directions)}


class VelocityTrial(Trial):
    """Constant-velocity runs of one motor at a time (others held), several speeds, both directions over the same
    span; the steady part of each run is a segment (joint, direction, speed)."""
    name = "velocity"

    def __init__(self, ctx):
        super().__init__(ctx)
        c, n = self.cfg, ctx.n
        self.pose = ctx.check_pose(c.get("pose", [0.0] * n), "velocity.pose")
        self.axes = [int(a) for a in c.get("axes", range(n))]
        fr = c.get("speed_fractions", [0.1, 0.3, 0.6, 0.9])
        self.max_speed = _vec(c, "max_speed", n, self.path, default=list(0.8 * ctx.vlim))
        if np.any(self.max_speed > ctx.vlim):
            raise ConfigError(self.path, "velocity.max_speed", f"above the drive velocity limit {ctx.vlim.tolist()}")
        self.fractions = [float(f) for f in fr]
        self.acc = _vec(c, "acceleration", n, self.path, default=list(0.5 * ctx.acc_max))
        self.steady_s = float(c.get("steady_s", 0.8))
        self.settle_s = float(c.get("settle_s", 0.15))
        self.mode = str(c.get("mode", "cst")).lower()
        if self.mode not in ("cst", "csv"):
            raise ConfigError(self.path, "velocity.mode", f"{self.mode!r}: cst (host loops, mode 10) or csv (the "
                              f"drive's velocity loop, mode 9)")

    def runs(self, i: int):
        m_pose = self.ctx.motor(self.pose)
        lo, hi = self.ctx.axis_range(m_pose, i)
        out = []
        for f in self.fractions:
            v = f * self.max_speed[i]
            ta = v / self.acc[i]
            L = min(hi - lo, v * (self.steady_s + self.settle_s) + v * ta)
            tc = (L - v * ta) / v
            if tc < self.settle_s + 0.1:
                continue
            c = min(max(m_pose[i], lo + L / 2), hi - L / 2)
            out.append((v, c - L / 2, c + L / 2, ta, tc))
        return m_pose, out

    def estimate_s(self) -> float:
        tot = 0.0
        for i in self.axes:
            _, runs = self.runs(i)
            tot += 1.0 + sum(2 * (r[3] * 2 + r[4] + 0.1) + 0.6 for r in runs)
        return tot

    def plan(self):
        ctx = self.ctx
        nseg = 0
        for i in self.axes:
            if self.mode == "csv":
                yield from self.with_csv(self.axis_runs(i), (i,))
                yield from self.hold(self.ctx.motor(self.pose), 0.2)
            else:
                yield from self.axis_runs(i)
            nseg += 2 * len(self.runs(i)[1])
        self.summary = {"segments": nseg}

    def axis_runs(self, i):
        ctx = self.ctx
        if True:
            m_pose, runs = self.runs(i)
            yield from self.move(m_pose)
            for v, a, b, ta, tc in runs:
                start = m_pose.copy()
                start[i] = a
                yield from self.move(start, speed_fraction=0.6, min_s=0.3)
                yield from self.hold(start, 0.15)
                for direction, (p0, p1) in ((1, (a, b)), (-1, (b, a))):
                    yield from self.run(i, m_pose, p0, p1, v, ta, tc, direction)
                    end = m_pose.copy()
                    end[i] = p1
                    yield from self.hold(end, 0.1)
            yield from self.move(m_pose, speed_fraction=0.6)

    def run(self, i, m_pose, p0, p1, v, ta, tc, direction):
        ctx = self.ctx
        acc = v / ta
        T = 2 * ta + tc
        N = self.n_cycles(T)
        seg_on, seg_off = ta + self.settle_s, ta + tc
        in_seg = False
        q = m_pose.copy()
        dq = np.zeros(ctx.n)
        for k in range(1, N + 1):
            t = k * ctx.dt
            if t < ta:
                s, ds = 0.5 * acc * t * t, acc * t
            elif t < ta + tc:
                s, ds = 0.5 * acc * ta * ta + v * (t - ta), v
            else:
                td = min(t - ta - tc, ta)
                s, ds = 0.5 * acc * ta * ta + v * tc + v * td - 0.5 * acc * td * td, v - acc * td
            q[i] = p0 + direction * s
            dq[i] = direction * ds
            if not in_seg and t >= seg_on and t < seg_off:
                in_seg = True
                self.emit("segment_start", joint=i, direction=direction, speed=v)
            if in_seg and t >= seg_off:
                in_seg = False
                self.emit("segment_end", joint=i, direction=direction, speed=v)
            yield Ref(q.copy(), dq.copy())
        if in_seg:
            self.emit("segment_end", joint=i, direction=direction, speed=v)


class AccelerationTrial(Trial):
    """All axes together: straight strokes in motor space between joint-space points, each with constant
    acceleration for the first half and constant deceleration for the second (the paper's simultaneous test)."""
    name = "acceleration"

    def __init__(self, ctx):
        super().__init__(ctx)
        c, n = self.cfg, ctx.n
        self.center = ctx.check_pose(c.get("center", [0.0] * n), "acceleration.center")
        self.amplitude = float(c.get("amplitude", 0.6))
        self.durations = [float(x) for x in c.get("durations", [1.6, 1.2, 1.0])]
        self.strokes = int(c.get("strokes_per_duration", 4))
        self.speed_fraction = float(c.get("speed_fraction", 0.8))
        self.pause_s = float(c.get("pause_s", 0.2))
        self.seed = int(c.get("seed", 1)) + ctx.seed
        self._plan = self._make_strokes()

    def _make_strokes(self):
        ctx = self.ctx
        rng = np.random.default_rng(self.seed)
        lo, hi = ctx.inner_lo_hi()
        half = np.minimum(self.center - lo, hi - self.center)
        strokes = []
        p = self.center.copy()
        for T in self.durations:
            for s in range(self.strokes):
                u = rng.uniform(0.5, 1.0, ctx.n) * rng.choice([-1.0, 1.0], ctx.n)
                if strokes:  # mostly reverse the previous stroke so the arm sweeps through the range
                    u = -np.sign(strokes[-1][2] - strokes[-1][1] + 1e-12) * np.abs(u) * np.where(
                        rng.uniform(size=ctx.n) < 0.8, 1.0, -1.0)
                target = self.center + self.amplitude * half * u
                d = ctx.motor(target) - ctx.motor(p)
                # constant acc a = 4 d / T^2, peak speed 2 d / T
                sc = min(1.0, float(np.min(self.speed_fraction * ctx.vlim * T / 2 / np.maximum(np.abs(d), 1e-12))),
                         float(np.min(ctx.acc_max * T * T / 4 / np.maximum(np.abs(d), 1e-12))))
                qj_target = ctx.joint(ctx.motor(p) + sc * d)
                strokes.append((T, p.copy(), qj_target))
                p = qj_target
        return strokes

    def estimate_s(self) -> float:
        return 2.0 + sum(T + self.pause_s for T, _, _ in self._plan)

    def plan(self):
        ctx = self.ctx
        yield from self.move(ctx.motor(self.center))
        yield from self.hold(ctx.motor(self.center), 0.3)
        for k, (T, pj, qj) in enumerate(self._plan):
            m0, m1 = ctx.motor(pj), ctx.motor(qj)
            d = m1 - m0
            acc = 4 * d / (T * T)
            N = self.n_cycles(T)
            self.emit("segment_start", detail=f"stroke {k}: constant acceleration {np.round(acc, 1).tolist()} "
                                              f"rad/s^2 (motor) for {T / 2:g} s, then deceleration")
            for j in range(1, N + 1):
                t = j * ctx.dt
                if t <= T / 2:
                    q, dq = m0 + 0.5 * acc * t * t, acc * t
                else:
                    tr = T - t
                    q, dq = m1 - 0.5 * acc * tr * tr, acc * tr
                yield Ref(q, dq)
            self.emit("segment_end", detail=f"stroke {k}")
            yield from self.hold(m1, self.pause_s)
        self.summary = {"strokes": len(self._plan)}


class FourierTrial(Trial):
    """Finite Fourier series per joint around a center pose, scaled into the joint envelope (minus margin), the
    motor speed limit (x speed_fraction) and max_acceleration; faded in and out over one second."""
    name = "excitation"
    default_seed = 11

    def __init__(self, ctx):
        super().__init__(ctx)
        c, n = self.cfg, ctx.n
        self.center = ctx.check_pose(c.get("center", [0.0] * n), f"{self.name}.center")
        self.period = float(c.get("period_s", 10.0))
        self.harmonics = int(c.get("harmonics", 5))
        self.periods = float(c.get("periods", 2))
        self.speed_fraction = float(c.get("speed_fraction", 0.6))
        self.amplitude = float(c.get("amplitude", 0.8))
        self.fade_s = float(c.get("fade_s", 1.0))
        self.seed = int(c.get("seed", self.default_seed)) + ctx.seed
        self._coef()

    def _coef(self):
        ctx = self.ctx
        rng = np.random.default_rng(self.seed)
        H, n = self.harmonics, ctx.n
        w = 2 * np.pi / self.period
        k = np.arange(1, H + 1)
        a = rng.normal(size=(n, H)) / k
        b = rng.normal(size=(n, H)) / k
        t = np.linspace(0, self.period, 2000, endpoint=False)
        S, C = np.sin(np.outer(k * w, t)), np.cos(np.outer(k * w, t))
        kw = (k * w)[:, None]
        q = a @ (S / kw) - b @ (C / kw)
        q -= q.mean(axis=1, keepdims=True)
        dq = a @ C + b @ S
        ddq = -a @ (S * kw) + b @ (C * kw)
        lo, hi = ctx.inner_lo_hi()
        room = np.minimum(self.center - lo, hi - self.center) * self.amplitude
        s_pos = room / np.maximum(np.abs(q).max(axis=1), 1e-12)
        # joint-space scale per joint, then a common factor for motor speed / acceleration (K couples the wrist)
        self.scale = s_pos
        dqm = ctx.Kinv @ (dq * s_pos[:, None])
        ddqm = ctx.Kinv @ (ddq * s_pos[:, None])
        g = min(1.0, float(np.min(self.speed_fraction * ctx.vlim / np.maximum(np.abs(dqm).max(axis=1), 1e-12))),
                float(np.min(0.8 * ctx.acc_max / np.maximum(np.abs(ddqm).max(axis=1), 1e-12))))
        self.scale = s_pos * g
        self.a, self.b, self.w, self.k = a, b, w, k
        self.q_mean = (a @ (S / kw) - b @ (C / kw)).mean(axis=1)

    def q_dq(self, t: float):
        kw = self.k * self.w
        s, c = np.sin(kw * t), np.cos(kw * t)
        q = (self.a @ (s / kw) - self.b @ (c / kw)) - self.q_mean
        dq = self.a @ c + self.b @ s
        return q * self.scale, dq * self.scale

    def estimate_s(self) -> float:
        return self.periods * self.period + 2 * self.fade_s + 2.0

    def plan(self):
        ctx = self.ctx
        T = self.periods * self.period
        total = T + 2 * self.fade_s
        m_c = ctx.motor(self.center)
        yield from self.move(m_c)
        yield from self.hold(m_c, 0.3)
        self.emit("segment_start", detail=f"finite Fourier series: period {self.period:g} s, {self.harmonics} "
                                          f"harmonics, seed {self.seed}")
        N = self.n_cycles(total)
        for j in range(1, N + 1):
            t = j * ctx.dt
            # fade in/out with a quintic window over fade_s
            if t < self.fade_s:
                x = t / self.fade_s
            elif t > total - self.fade_s:
                x = (total - t) / self.fade_s
            else:
                x = 1.0
            x = min(max(x, 0.0), 1.0)
            wgt = 10 * x**3 - 15 * x**4 + 6 * x**5
            dwgt = (30 * x**2 - 60 * x**3 + 30 * x**4) / self.fade_s * (1 if t < self.fade_s else
                                                                        (-1 if t > total - self.fade_s else 0))
            qj, dqj = self.q_dq(t - self.fade_s)
            q = self.center + wgt * qj
            dq = wgt * dqj + dwgt * qj
            yield Ref(ctx.motor(q), ctx.Kinv @ dq)
        self.emit("segment_end", detail="finite Fourier series")
        yield from self.hold(m_c, 0.3)
        self.summary = {"duration_s": round(total, 2)}


class ValidationTrial(FourierTrial):
    """A second finite Fourier series (own center, period and seed) to validate an identified model."""
    name = "validation"
    default_seed = 29


TRIALS = {"static": StaticTrial, "velocity": VelocityTrial, "acceleration": AccelerationTrial,
          "excitation": FourierTrial, "validation": ValidationTrial}


def make_trials(names, ctx: TrialContext) -> list[Trial]:
    out = []
    for name in names:
        if name not in TRIALS:
            raise ConfigError(ctx.path, None, f"unknown trial {name!r}; one of {', '.join(TRIALS)} or 'all'")
        out.append(TRIALS[name](ctx))
    return out


def expand_trial_names(spec: str | list[str]) -> list[str]:
    names = spec.split(",") if isinstance(spec, str) else list(spec)
    out = []
    for nm in names:
        nm = nm.strip()
        out.extend(TRIAL_NAMES if nm == "all" else [nm])
    return out
