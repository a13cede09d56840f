"""Signals: motor angles -> filtered angles, velocities, accelerations and torques (the paper's digital filters).

The paper differentiates the encoder angles through digital filters, cut-off **50 Hz for velocity** and **7 Hz for
acceleration**. :func:`choose_cutoffs` keeps those where the log's sample rate and motion allow and otherwise picks
admissible ones (always below Nyquist), with a one-line reason; ``js2-identify`` uses it unless cut-offs are given. Here, zero-phase Butterworth filters (``scipy.signal.sosfiltfilt``, forward + backward, no delay):

* ``q_motor``  = LP_vel(encoder angle)                     (rad, motor side)
* ``dq_motor`` = d/dt q_motor (central differences)         (rad/s, 50 Hz band)
* ``ddq_motor`` = LP_acc(d/dt dq_motor)                     (rad/s^2, 7 Hz band)
* ``tau``      = LP_acc(measured torque)                    (N m, on the log's torque side)

The torque is filtered with the acceleration's filter ("consistently"): any regressor column built from these signals
must pass through the same filter too (:meth:`Signals.filter_like_torque`, "parallel filtering"), so that a column and
the torque it explains have seen the same filter. Joint angles are ``theta = K theta_m + offset`` (eq. 1), K coupled
allowed.

Lost cycles: a gap in the cycle counter or a sample flagged ``valid = false`` is never silently interpolated over.
Gaps up to ``max_bridge`` cycles are bridged linearly *only so that the filters can run*, and every bridged sample plus
a guard band of ``trim_s`` on either side is excluded from estimation (``keep`` false); longer gaps split the record into
separate runs, each filtered on its own with ``trim_s`` cut at both ends. :attr:`Signals.note` says what was done.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import butter, detrend, sosfiltfilt, welch

from js2spec.errors import LogError

PAPER_FC_VELOCITY_HZ = 50.0       # the paper's velocity filter cut-off
PAPER_FC_ACCELERATION_HZ = 7.0    # the paper's acceleration (and torque) filter cut-off
NYQUIST_MARGIN = 0.8              # chosen cut-offs stay at or below this fraction of the Nyquist frequency
MOTION_HEADROOM = 2.0             # the acceleration/torque cut-off is at least this multiple of the motion bandwidth


@dataclass
class FilterSettings:
    fc_velocity_hz: float = PAPER_FC_VELOCITY_HZ
    fc_acceleration_hz: float = PAPER_FC_ACCELERATION_HZ
    order: int = 4                    # Butterworth order (each pass; zero-phase doubles the attenuation)
    trim_s: float | None = None       # edge trim per run; default 1.5 / fc_acceleration
    max_bridge: int = 5               # longest gap (cycles) bridged for filtering (then excluded)
    reason: str = "given"             # why these cut-offs (written to model.yaml and the summary)

    @property
    def trim(self) -> float:
        return self.trim_s if self.trim_s is not None else 1.5 / self.fc_acceleration_hz


@dataclass
class Signals:
    """Filtered signals of one log on a regular grid (rows = cycles present or bridged). Arrays (N, n)."""

    t: np.ndarray
    fs: float
    q_motor: np.ndarray
    dq_motor: np.ndarray
    ddq_motor: np.ndarray
    tau: np.ndarray
    tau_raw: np.ndarray
    q_motor_raw: np.ndarray
    keep: np.ndarray                 # (N,) usable for estimation
    runs: list[tuple[int, int]]      # contiguous filtered stretches [start, stop)
    settings: FilterSettings
    n_lost: int = 0
    n_invalid: int = 0
    n_bridged: int = 0
    note: str = ""
    source: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.q_motor.shape[1]

    def filter_like_torque(self, X: np.ndarray) -> np.ndarray:
        """Apply the torque's (acceleration) zero-phase filter along axis 0, run by run (parallel filtering)."""
        return _lp_runs(X, self.settings.fc_acceleration_hz, self.fs, self.settings.order, self.runs)

    def acceleration_unfiltered(self) -> np.ndarray:
        """d/dt dq_motor by central differences, run by run (rad/s^2; the velocity's band, not yet the torque's
        filter): what a model's torque is predicted from *before* :meth:`filter_like_torque`, as identification
        builds its regressor (``pipeline._regressor_rows``). ``ddq_motor`` has the torque's filter already: a
        prediction from it, filtered like the torque, has its inertial part filtered twice (|H|^4 against the
        torque's |H|^2: 6 % low at 5 Hz with the paper's 7 Hz filter)."""
        out = np.full_like(self.dq_motor, np.nan)
        for a, b in self.runs:
            if b - a > 1:
                out[a:b] = np.gradient(self.dq_motor[a:b], 1.0 / self.fs, axis=0)
        return out

    def mask_between(self, t0: float, t1: float) -> np.ndarray:
        return self.keep & (self.t >= t0) & (self.t <= t1)


def motion_bandwidth(q: np.ndarray, fs_hz: float, fraction: float = 0.999) -> float:
    """Bandwidth of a motion (Hz): the frequency below which ``fraction`` of the power of the detrended positions
    lies (Welch spectrum, 8 s segments), the largest over the columns. Rows with NaN are dropped."""
    q = np.asarray(q, float)
    if q.ndim == 1:
        q = q[:, None]
    q = q[np.all(np.isfinite(q), axis=1)]
    if len(q) < 16:
        return float("nan")
    out = 0.0
    for k in range(q.shape[1]):
        f, P = welch(detrend(q[:, k]), fs=fs_hz, nperseg=min(len(q), int(8 * fs_hz)))
        tot = P.sum()
        if tot <= 0:
            continue
        out = max(out, float(f[min(np.searchsorted(np.cumsum(P) / tot, fraction), len(f) - 1)]))
    return out


def choose_cutoffs(fs_hz: float, motion_bandwidth_hz: float | None = None, fc_velocity_hz: float | None = None,
                   fc_acceleration_hz: float | None = None, order: int = 4) -> FilterSettings:
    """Filter cut-offs that follow the data: the paper's 50 Hz (velocity) and 7 Hz (acceleration and torque) where the
    sample rate and the motion allow, otherwise the nearest admissible values. ``reason`` says which rule applied.

    * velocity: ``min(50 Hz, 0.8 x Nyquist)`` -- the paper's value unless the log is sampled below 125 Hz;
    * acceleration/torque: ``max(7 Hz, 2 x motion bandwidth)`` (the motion's 99.9 % power frequency, see
      :func:`motion_bandwidth`, so a fast excitation is not filtered away), then at most the velocity cut-off and
      ``0.8 x Nyquist``.

    Cut-offs given by the caller are kept if they lie below the Nyquist frequency (else ``ValueError`` naming it).
    Used by ``identification.pipeline.identify`` when no cut-offs are given; callable by any consumer that filters
    js2 logs the same way (e.g. the diagnosis)."""
    fs_hz = float(fs_hz)
    if not fs_hz > 0:
        raise ValueError(f"sample rate {fs_hz} Hz must be positive")
    nyq = fs_hz / 2
    cap = NYQUIST_MARGIN * nyq
    for name, v in (("velocity", fc_velocity_hz), ("acceleration", fc_acceleration_hz)):
        if v is not None and not 0 < v < nyq:
            raise ValueError(f"{name} filter cut-off {v:g} Hz must lie between 0 and the Nyquist frequency "
                             f"{nyq:g} Hz of this {fs_hz:g} Hz log (or leave it out: it is then chosen from the data)")
    why = []
    if fc_velocity_hz is None:
        fv = min(PAPER_FC_VELOCITY_HZ, cap)
        why.append("velocity 50 Hz (paper)" if fv == PAPER_FC_VELOCITY_HZ else
                   f"velocity {fv:.3g} Hz = {NYQUIST_MARGIN:g} x Nyquist (the paper's 50 Hz is above what a "
                   f"{fs_hz:g} Hz log holds)")
    else:
        fv = float(fc_velocity_hz)
        why.append(f"velocity {fv:g} Hz (given)")
    if fc_acceleration_hz is None:
        bw = motion_bandwidth_hz if motion_bandwidth_hz is not None and np.isfinite(motion_bandwidth_hz) else 0.0
        fa = max(PAPER_FC_ACCELERATION_HZ, MOTION_HEADROOM * bw)
        if fa == PAPER_FC_ACCELERATION_HZ:
            txt = "acceleration/torque 7 Hz (paper)"
        else:
            txt = (f"acceleration/torque {fa:.3g} Hz = {MOTION_HEADROOM:g} x the motion bandwidth {bw:.3g} Hz "
                   f"(the paper's 7 Hz would filter the motion)")
        if fa > min(fv, cap):
            fa = min(fv, cap)
            txt = f"acceleration/torque {fa:.3g} Hz (capped at the velocity cut-off / {NYQUIST_MARGIN:g} x Nyquist)"
        why.append(txt)
    else:
        fa = float(fc_acceleration_hz)
        why.append(f"acceleration/torque {fa:g} Hz (given)")
    bwtxt = f", motion bandwidth {motion_bandwidth_hz:.3g} Hz" if motion_bandwidth_hz is not None and np.isfinite(
        motion_bandwidth_hz) else ""
    return FilterSettings(fc_velocity_hz=fv, fc_acceleration_hz=fa, order=order,
                          reason=f"{'; '.join(why)} (sample rate {fs_hz:g} Hz{bwtxt})")


def _sos(fc: float, fs: float, order: int):
    if not 0 < fc < fs / 2:
        raise ValueError(f"filter cut-off {fc} Hz must lie between 0 and the Nyquist frequency {fs / 2} Hz")
    return butter(order, fc, btype="low", fs=fs, output="sos")


def filtfilt_padlen(sos: np.ndarray, n: int) -> int:
    """The odd extension's length for a zero-phase pass of ``sos`` over a run of n samples: scipy's default for
    sosfiltfilt, 3 (2 sections + 1) x 4, shortened to fit the run (n - 1, at least 0). One rule for every filtering
    of a run, here and in the diagnosis's torque band."""
    return max(min(3 * (2 * len(sos) + 1) * 4, n - 1), 0)


def _lp_runs(X: np.ndarray, fc: float, fs: float, order: int, runs) -> np.ndarray:
    sos = _sos(fc, fs, order)
    out = np.empty_like(X, dtype=float)
    for a, b in runs:
        seg = X[a:b]
        out[a:b] = sosfiltfilt(sos, seg, axis=0, padlen=filtfilt_padlen(sos, len(seg)))
    return out


def lowpass(x: np.ndarray, fc: float, fs: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass along axis 0."""
    return _lp_runs(np.asarray(x, float), fc, fs, order, [(0, len(x))])


def process(t: np.ndarray, cycle: np.ndarray, motor_position: np.ndarray, torque: np.ndarray,
            valid: np.ndarray | None, fs: float, settings: FilterSettings | None = None, source: str = "") -> Signals:
    """Filter and differentiate one log's feedback (see module docstring). ``fs`` is the nominal cycle rate (Hz)."""
    s = settings or FilterSettings()
    cycle = np.asarray(cycle, dtype=np.int64)
    N0, n = motor_position.shape
    if N0 < 4:
        raise LogError(source or None, f"only {N0} feedback samples: too short to filter")
    if valid is None:
        valid = np.ones((N0, n), dtype=bool)
    finite = np.all(np.isfinite(motor_position), axis=1) & np.all(np.isfinite(torque), axis=1)
    good = np.all(valid, axis=1) & finite
    n_invalid = int(np.sum(~good))
    # regular grid from the cycle counter
    c0 = int(cycle[0])
    idx = cycle - c0
    if np.any(np.diff(idx) <= 0):
        # non-monotonic counter: fall back to sample order
        idx = np.arange(N0)
    Ng = int(idx[-1]) + 1
    present = np.zeros(Ng, dtype=bool)
    present[idx[good]] = True
    n_lost = int(Ng - N0)
    qg = np.full((Ng, n), np.nan)
    tg = np.full((Ng, n), np.nan)
    qg[idx[good]] = motor_position[good]
    tg[idx[good]] = torque[good]
    t_grid = float(t[0]) + np.arange(Ng) / fs
    # runs separated by gaps longer than max_bridge; short gaps bridged (and later excluded)
    miss = ~present
    runs, bridged = [], np.zeros(Ng, dtype=bool)
    start = None
    k = 0
    while k < Ng:
        if present[k]:
            if start is None:
                start = k
            k += 1
            continue
        j = k
        while j < Ng and miss[j]:
            j += 1
        gap = j - k
        if start is not None and j < Ng and gap <= s.max_bridge:
            bridged[k:j] = True
            k = j
            continue
        if start is not None:
            runs.append((start, k))
        start = None
        k = j
    if start is not None:
        runs.append((start, Ng))
    min_len = max(int(4 * s.trim * fs), 30)
    dropped = [(a, b) for a, b in runs if b - a < min_len]
    runs = [(a, b) for a, b in runs if b - a >= min_len]
    if not runs:
        raise LogError(source or None, f"no stretch of at least {min_len} consecutive valid cycles to filter")
    for a, b in runs:
        seg = slice(a, b)
        ok = present[seg]
        x = np.arange(a, b)
        for arr in (qg, tg):
            for j in range(n):
                col = arr[seg, j]
                col[~ok] = np.interp(x[~ok], x[ok], col[ok])
    q_f = np.full((Ng, n), np.nan)
    dq = np.full((Ng, n), np.nan)
    ddq = np.full((Ng, n), np.nan)
    tau_f = np.full((Ng, n), np.nan)
    sos_v = _sos(s.fc_velocity_hz, fs, s.order)
    sos_a = _sos(s.fc_acceleration_hz, fs, s.order)
    for a, b in runs:
        seg = slice(a, b)
        pad = min(3 * (2 * len(sos_v) + 1) * 4, b - a - 1)
        q_f[seg] = sosfiltfilt(sos_v, qg[seg], axis=0, padlen=pad)
        dq[seg] = np.gradient(q_f[seg], 1.0 / fs, axis=0)
        ddq[seg] = sosfiltfilt(sos_a, np.gradient(dq[seg], 1.0 / fs, axis=0), axis=0, padlen=pad)
        tau_f[seg] = sosfiltfilt(sos_a, tg[seg], axis=0, padlen=pad)
    keep = np.zeros(Ng, dtype=bool)
    ntrim = int(round(s.trim * fs))
    for a, b in runs:
        keep[a + ntrim:b - ntrim] = True
    if bridged.any():
        # exclude bridged samples and a guard band around them
        bi = np.flatnonzero(bridged)
        guard = np.zeros(Ng, dtype=bool)
        for k in bi:
            guard[max(0, k - ntrim):k + ntrim + 1] = True
        keep &= ~guard
    parts = []
    if n_lost:
        parts.append(f"{n_lost} lost cycles (counter gaps)")
    if n_invalid:
        parts.append(f"{n_invalid} samples flagged invalid or not finite")
    if bridged.any():
        parts.append(f"{int(bridged.sum())} missing cycles in gaps <= {s.max_bridge} bridged for filtering only and "
                     f"excluded with a {s.trim:.3f} s guard band")
    if len(runs) > 1 or dropped:
        parts.append(f"record split into {len(runs)} runs at longer gaps"
                     + (f", {len(dropped)} run(s) shorter than {min_len} cycles dropped" if dropped else ""))
    note = "; ".join(parts) if parts else "no lost or invalid cycles"
    return Signals(t=t_grid, fs=fs, q_motor=q_f, dq_motor=dq, ddq_motor=ddq, tau=tau_f, tau_raw=tg,
                   q_motor_raw=qg, keep=keep, runs=runs, settings=s, n_lost=n_lost, n_invalid=n_invalid,
                   n_bridged=int(bridged.sum()), note=note, source=source)


def from_log(log, settings: FilterSettings | None = None) -> Signals:
    """:func:`process` applied to a ``js2spec.log.Js2Log``."""
    fb = log.feedback
    sig = process(fb.t, fb.cycle, fb.motor_position, fb.torque, fb.valid, float(log.cycle_hz), settings,
                  source=str(log.path))
    return sig
