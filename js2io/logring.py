"""RingLog: the cycle loop hands its samples to a writer thread through a preallocated ring buffer.

On the cycle path a feedback or command sample is copied into preallocated numpy rows (no JSON, no compression, no
file I/O, no new arrays); a writer thread turns the rows into `js2spec.log.LogWriter` calls every few milliseconds
(JSON encoding, zstd chunks and file flushes happen there; zstd compresses without the GIL). Rare calls (events,
metadata, joint states) are queued in the same ring, so the order of the log is the order of the calls.

A write that fails in the writer thread (full disk, closed file) is remembered in `error` as one line and every later
write is skipped, exactly as `session.GuardedLog` does for a synchronous writer; the session sees the flag on its next
cycle. A ring that fills up (the writer more than `capacity` samples behind) makes the cycle wait, counted in
`stalls`, rather than lose samples.
"""
from __future__ import annotations

import threading
import time

import numpy as np

_FB, _CMD, _CALL = 1, 2, 3
_HAS_CUR, _HAS_STATUS, _HAS_VALID, _HAS_VEL = 1, 2, 4, 8


def _below_the_cycle() -> None:
    """In a SCHED_FIFO process, run this thread one real-time priority below the cycle: it still preempts ordinary
    processes (so it never sits preempted while holding the GIL the cycle waits for), the cycle preempts it."""
    import os
    try:
        if os.sched_getscheduler(0) == os.SCHED_FIFO:
            prio = os.sched_getparam(0).sched_priority
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(max(1, prio - 1)))
    except (AttributeError, OSError):
        pass


class RingLog:
    def __init__(self, writer, capacity: int = 8192, describe=None, poll_s: float = 0.004):
        self.writer = writer
        self.path = writer.path
        self.n = n = writer.n
        self.capacity = cap = int(capacity)
        self.kind = np.zeros(cap, dtype=np.int8)
        self.opt = np.zeros(cap, dtype=np.int8)
        self.cycle = np.zeros(cap, dtype=np.int64)
        self.t = np.zeros(cap)
        self.a = np.zeros((cap, n))         # feedback: motor position | command: target torque
        self.b = np.zeros((cap, n))         # feedback: torque         | command: target velocity
        self.c = np.zeros((cap, n))         # feedback: motor current
        self.ints = np.zeros((cap, n), dtype=np.int64)   # feedback: status | command: mode
        self.valid = np.zeros((cap, n), dtype=bool)
        self.calls: list = [None] * cap     # rare calls: (name, args, kwargs)
        self.head = 0                       # written by the cycle thread only
        self.tail = 0                       # written by the writer thread only
        self.stalls = 0
        self.error: str | None = None
        self.closed = False
        self._describe = describe or (lambda e: f"{type(e).__name__}: {e}")
        self._poll_s = poll_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="js2-log-writer", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ the cycle thread
    def _slot(self) -> int:
        while self.head - self.tail >= self.capacity:
            self.stalls += 1
            time.sleep(self._poll_s / 4)
        return self.head % self.capacity

    def feedback(self, cycle, t, motor_position, torque, motor_current=None, status=None, valid=None) -> None:
        k = self._slot()
        opt = 0
        self.cycle[k] = cycle
        self.t[k] = t
        self.a[k] = motor_position
        self.b[k] = torque
        if motor_current is not None:
            self.c[k] = motor_current
            opt |= _HAS_CUR
        if status is not None:
            self.ints[k] = status
            opt |= _HAS_STATUS
        if valid is not None:
            self.valid[k] = valid
            opt |= _HAS_VALID
        self.opt[k] = opt
        self.kind[k] = _FB
        self.head += 1

    def command(self, cycle, t, mode, target_torque, target_velocity=None) -> None:
        k = self._slot()
        self.cycle[k] = cycle
        self.t[k] = t
        self.ints[k] = mode
        self.a[k] = target_torque
        opt = 0
        if target_velocity is not None:
            self.b[k] = target_velocity
            opt |= _HAS_VEL
        self.opt[k] = opt
        self.kind[k] = _CMD
        self.head += 1

    def _call(self, name, *args, **kwargs) -> None:
        k = self._slot()
        self.calls[k] = (name, args, kwargs)
        self.kind[k] = _CALL
        self.head += 1

    def event(self, *args, **kwargs) -> None:
        self._call("event", *args, **kwargs)

    def joint_state(self, *args, **kwargs) -> None:
        self._call("joint_state", *args, **kwargs)

    def metadata(self, *args, **kwargs) -> None:
        self._call("metadata", *args, **kwargs)

    def attach(self, *args, **kwargs) -> None:
        self._call("attach", *args, **kwargs)

    def flush(self, *args, **kwargs) -> None:
        self._call("flush", *args, **kwargs)

    # ------------------------------------------------------------------ the writer thread
    def _write(self, k: int) -> None:
        w, kind, opt = self.writer, self.kind[k], int(self.opt[k])
        if kind == _FB:
            w.feedback(int(self.cycle[k]), float(self.t[k]), self.a[k], self.b[k],
                       motor_current=self.c[k] if opt & _HAS_CUR else None,
                       status=self.ints[k] if opt & _HAS_STATUS else None,
                       valid=self.valid[k] if opt & _HAS_VALID else None)
        elif kind == _CMD:
            w.command(int(self.cycle[k]), float(self.t[k]), self.ints[k], self.a[k],
                      target_velocity=self.b[k] if opt & _HAS_VEL else None)
        else:
            name, args, kwargs = self.calls[k]
            self.calls[k] = None
            getattr(w, name)(*args, **kwargs)

    def _name(self, k: int) -> str:
        kind = self.kind[k]
        return "feedback" if kind == _FB else "command" if kind == _CMD else (self.calls[k] or ("?",))[0]

    def _drain(self) -> None:
        while self.tail < self.head:
            k = self.tail % self.capacity
            if self.error is None:
                try:
                    self._write(k)
                except Exception as e:   # noqa: BLE001 - any failure of the log must not reach the cycle loop
                    self.error = f"log write failed ({self._name(k)}): {self._describe(e)}"
            self.calls[k] = None
            self.tail += 1

    def _run(self) -> None:
        _below_the_cycle()
        while True:
            stopping = self._stop.is_set()
            self._drain()
            if stopping:
                return
            self._stop.wait(self._poll_s)

    # ------------------------------------------------------------------ end
    def _join(self) -> None:
        self._stop.set()
        self._thread.join()
        self._drain()     # anything queued after the thread's last look

    def close(self) -> None:
        """Write everything queued, then close the file. Raises what closing raises (GuardedLog catches it)."""
        if self.closed:
            return
        self._join()
        self.closed = True
        if self.error is None:
            self.writer.close()
        else:
            self.writer.abandon()

    def abandon(self) -> None:
        """After a failed write: stop the thread, close the file without the footer (the reader recovers chunks)."""
        if self.closed:
            return
        self._join()
        self.closed = True
        self.writer.abandon()
