"""Real-time scheduling for the cycle loop (Linux): SCHED_FIFO for this process; threads created afterwards
(python-can's notifier, heartbeat senders, the simulator) inherit it. Needs root, CAP_SYS_NICE or an rtprio limit."""
from __future__ import annotations

import os

from js2spec.errors import Js2Error


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
        raise Js2Error(f"--rt-priority {priority}: not permitted; run as root, grant CAP_SYS_NICE, or set an rtprio "
                       f"limit (/etc/security/limits.conf), or drop the option") from None
    return f"SCHED_FIFO priority {priority}"
