"""Drive groups chosen by name, as python-can chooses interfaces: an entry-point registry, so js2io knows no
implementation but its own CANopen master.

A package offers a rig (a DriveGroup with whatever it needs around it: a simulator, a bus, a process) under the
entry-point group `js2.drive_groups`:

    [project.entry-points."js2.drive_groups"]
    sim = "hil_sim.rigs:in_process"

The entry point is a factory `factory(robot, *, cycle_hz, seed, faults, realtime, rt_priority, cpu) -> rig` returning a
started rig with `group` (a `js2io.group.DriveGroup`, not yet opened), `where` (one line for the console) and
`close()`. js2-acquire takes `--sim NAME`; this project's own (hil_sim) are `sim`, `sim-direct` and `sim-process`.
"""
from __future__ import annotations

from importlib.metadata import entry_points

from js2spec.errors import Js2Error

ENTRY_POINT_GROUP = "js2.drive_groups"


def available() -> dict:
    """name -> entry point, of every installed rig."""
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def open_rig(name: str, robot, **kw):
    """Load the rig `name` from the registry and start it (kw as in the module docstring)."""
    eps = available()
    if name not in eps:
        have = ", ".join(sorted(eps)) or "none"
        raise Js2Error(f"--sim {name}: no drive group of that name is installed (installed: {have}); a package "
                       f"offers one under [project.entry-points.\"{ENTRY_POINT_GROUP}\"] -- after adding one, "
                       f"reinstall it (bash scripts/install.sh)")
    try:
        factory = eps[name].load()
    except (ImportError, AttributeError) as e:
        raise Js2Error(f"--sim {name}: its entry point {eps[name].value} cannot be loaded ({e}); reinstall the "
                       f"package that provides it") from None
    return factory(robot, **kw)
