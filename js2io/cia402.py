"""CiA 402 definitions, the one place both sides import: the master (js2io) and the simulated drives (hil_sim).

Statusword masks, controlword commands and mode numbers are canopen's own (`canopen.profiles.p402.State402`,
`OperationMode`); what canopen does not provide is added here: the master's per-cycle controlword logic (canopen's
`BaseNode402` walks the state machine by blocking SDO/PDO calls, not one step per SYNC) and the EMCY codes. No I/O.
"""
from __future__ import annotations

from canopen.profiles.p402 import OperationMode, State402

NOT_READY = "NOT READY TO SWITCH ON"
SWITCH_ON_DISABLED = "SWITCH ON DISABLED"
READY = "READY TO SWITCH ON"
SWITCHED_ON = "SWITCHED ON"
ENABLED = "OPERATION ENABLED"
QUICK_STOP = "QUICK STOP ACTIVE"
FAULT_REACTION = "FAULT REACTION ACTIVE"
FAULT = "FAULT"

# Statusword (0x6041): (mask, value, state); the eight patterns exclude each other, so the order does not matter
_SW = tuple((mask, value, name) for name, (mask, value) in State402.SW_MASK.items())
assert {n for _, _, n in _SW} == {NOT_READY, SWITCH_ON_DISABLED, READY, SWITCHED_ON, ENABLED, QUICK_STOP,
                                   FAULT_REACTION, FAULT}

STATUS_BITS = {name: value for _, value, name in _SW}    # the state bits a drive reports in each state

# Controlword (0x6040) commands
CW_SHUTDOWN = State402.CW_SHUTDOWN
CW_SWITCH_ON = State402.CW_SWITCH_ON
CW_ENABLE = State402.CW_OPERATION_ENABLED
CW_DISABLE_VOLTAGE = State402.CW_DISABLE_VOLTAGE
CW_QUICK_STOP = State402.CW_QUICK_STOP
CW_FAULT_RESET = State402.CW_SWITCH_ON_DISABLED     # bit 7, fault reset (canopen names it by its target state)

MODE_CST = OperationMode.CYCLIC_SYNCHRONOUS_TORQUE
MODE_CSV = OperationMode.CYCLIC_SYNCHRONOUS_VELOCITY
MODE_NAMES = {MODE_CST: "CST", MODE_CSV: "CSV", OperationMode.CYCLIC_SYNCHRONOUS_POSITION: "CSP",
              OperationMode.PROFILED_TORQUE: "PT", OperationMode.PROFILED_VELOCITY: "PV",
              OperationMode.PROFILED_POSITION: "PP", OperationMode.HOMING: "HM"}


def state_of(statusword: int) -> str:
    for mask, value, name in _SW:
        if statusword & mask == value:
            return name
    return NOT_READY


def next_controlword(state: str, target: str, last_cw: int) -> int:
    """The controlword a master sends this cycle to walk a drive from `state` towards `target`.

    target: 'enabled' (OPERATION ENABLED), 'disabled' (SWITCH ON DISABLED), 'quick_stop' (QUICK STOP ACTIVE),
    'reset' (clear a fault, then stay disabled). A fault reset needs a 0->1 edge on bit 7: after a cycle with
    bit 7 set the next one clears it.
    """
    if target == "quick_stop":
        if state in (ENABLED, QUICK_STOP):
            return CW_QUICK_STOP
        return CW_DISABLE_VOLTAGE
    if target == "disabled":
        return CW_DISABLE_VOLTAGE
    if state == FAULT:
        # rising edge on bit 7: low for one cycle, then high
        return CW_DISABLE_VOLTAGE if last_cw & CW_FAULT_RESET else CW_FAULT_RESET
    if target == "reset":
        return CW_DISABLE_VOLTAGE
    if state == FAULT_REACTION:
        return CW_DISABLE_VOLTAGE
    if state in (SWITCH_ON_DISABLED, NOT_READY):
        return CW_SHUTDOWN
    if state == READY:
        return CW_SWITCH_ON
    if state in (SWITCHED_ON, ENABLED):
        return CW_ENABLE
    if state == QUICK_STOP:
        return CW_DISABLE_VOLTAGE
    return CW_SHUTDOWN


# EMCY error codes (CiA 301 / 402) that the drives and the simulator use.
EMCY_GENERIC = 0x1000
EMCY_OVERCURRENT = 0x2310
EMCY_HEARTBEAT = 0x8130
EMCY_POSITION_LIMIT = 0x8612
EMCY_NAMES = {0x0000: "error reset / no error", 0x1000: "generic error", 0x2310: "continuous over-current",
              0x3210: "DC link over-voltage", 0x4310: "drive over-temperature", 0x8130: "life guard / heartbeat error",
              0x8611: "following error", 0x8612: "software position limit exceeded"}
