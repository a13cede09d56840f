"""CiA 402 power state machine: statusword decoding and the master's controlword logic (no I/O here)."""
from __future__ import annotations

# Statusword (0x6041) masks/values, as in CiA 402 and canopen's State402.SW_MASK.
NOT_READY = "NOT READY TO SWITCH ON"
SWITCH_ON_DISABLED = "SWITCH ON DISABLED"
READY = "READY TO SWITCH ON"
SWITCHED_ON = "SWITCHED ON"
ENABLED = "OPERATION ENABLED"
QUICK_STOP = "QUICK STOP ACTIVE"
FAULT_REACTION = "FAULT REACTION ACTIVE"
FAULT = "FAULT"

_SW = (
    (0x4F, 0x00, NOT_READY),
    (0x4F, 0x40, SWITCH_ON_DISABLED),
    (0x6F, 0x21, READY),
    (0x6F, 0x23, SWITCHED_ON),
    (0x6F, 0x27, ENABLED),
    (0x6F, 0x07, QUICK_STOP),
    (0x4F, 0x0F, FAULT_REACTION),
    (0x4F, 0x08, FAULT),
)

STATUS_BITS = {ENABLED: 0x27, QUICK_STOP: 0x07, FAULT: 0x08, FAULT_REACTION: 0x0F, SWITCH_ON_DISABLED: 0x40,
               READY: 0x21, SWITCHED_ON: 0x23, NOT_READY: 0x00}

# Controlword (0x6040) commands.
CW_SHUTDOWN = 0x06
CW_SWITCH_ON = 0x07
CW_ENABLE = 0x0F
CW_DISABLE_VOLTAGE = 0x00
CW_QUICK_STOP = 0x02
CW_FAULT_RESET = 0x80

MODE_CST = 10
MODE_CSV = 9
MODE_NAMES = {10: "CST", 9: "CSV", 8: "CSP", 4: "PT", 3: "PV", 1: "PP", 6: "HM"}


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
EMCY_NAMES = {0x0000: "error reset / no error", 0x1000: "generic error", 0x2310: "continuous over-current",
              0x3210: "DC link over-voltage", 0x4310: "drive over-temperature", 0x8130: "life guard / heartbeat error",
              0x8611: "following error", 0x8612: "software position limit exceeded"}
