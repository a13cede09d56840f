"""Real-time set-up for the cycle loop (Linux): SCHED_FIFO for this process (threads created afterwards -- python-can's
notifier, heartbeat senders -- inherit it) and its memory locked (mlockall, so no page fault stalls a cycle).
Needs root, CAP_SYS_NICE (+ CAP_IPC_LOCK or an memlock limit), or an rtprio limit; when not permitted the error says
so and what to do, nothing is silently skipped."""
from __future__ import annotations

import ctypes
import ctypes.util
import os

from js2spec.errors import Js2Error

MCL_CURRENT, MCL_FUTURE = 1, 2


def set_realtime_priority(priority: int) -> str:
    if priority <= 0:
        return "normal scheduling"
    if not hasattr(os, "sched_setscheduler"):
        raise Js2Error("--rt-priority needs Linux (SCHED_FIFO); drop the option on this system")
    lo, hi = os.sched_get_priority_min(os.SCHED_FIFO), os.sched_get_priority_max(os.SCHED_FIFO)
    if not lo <= priority <= hi:
        raise Js2Error(f"--rt-priority {priority}: SCHED_FIFO priorities are {lo}..{hi}")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError:
        raise Js2Error(f"--rt-priority {priority}: SCHED_FIFO not permitted for this user; run as root, grant "
                       f"CAP_SYS_NICE, or set an rtprio limit (/etc/security/limits.conf), or drop the option") from None
    return f"SCHED_FIFO priority {priority}"


def lock_memory() -> str:
    """mlockall(MCL_CURRENT | MCL_FUTURE) through libc."""
    name = ctypes.util.find_library("c")
    if name is None:
        raise Js2Error("--rt-priority: no C library found to lock memory (mlockall); drop the option")
    libc = ctypes.CDLL(name, use_errno=True)
    if libc.mlockall(MCL_CURRENT | MCL_FUTURE) != 0:
        err = ctypes.get_errno()
        raise Js2Error(f"--rt-priority: locking memory (mlockall) not permitted ({os.strerror(err)}); run as root, "
                       f"grant CAP_IPC_LOCK or raise the memlock limit (ulimit -l), or drop the option")
    return "memory locked"


def pin_cpu(cpu: int | None) -> str:
    """Run this process (and the threads it starts) on one CPU only."""
    if cpu is None:
        return ""
    if not hasattr(os, "sched_setaffinity"):
        raise Js2Error("--cpu needs Linux (sched_setaffinity); drop the option on this system")
    try:
        os.sched_setaffinity(0, {cpu})
    except (OSError, ValueError) as e:
        raise Js2Error(f"--cpu {cpu}: not possible here ({e}); the machine has CPUs 0..{os.cpu_count() - 1} "
                       f"(a container may allow fewer); choose another or drop the option") from None
    return f", pinned to CPU {cpu}"


def realtime_setup(priority: int, cpu: int | None = None) -> str:
    """--rt-priority N: SCHED_FIFO N and memory locked; 0: nothing. --cpu C: pinned to CPU C. Returns one line."""
    pinned = pin_cpu(cpu)
    if priority <= 0:
        return "normal scheduling (no --rt-priority)" + pinned
    who = "root" if hasattr(os, "geteuid") and os.geteuid() == 0 else f"uid {os.getuid()}"
    return f"{set_realtime_priority(priority)}, {lock_memory()} (permitted: running as {who}){pinned}"
