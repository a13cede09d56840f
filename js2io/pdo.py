"""The cyclic PDO layout, read from the drives' EDS: the one data source for the master and the simulated drives.

The layout is the EDS's default PDO configuration: every RPDO / TPDO whose default COB-ID (0x1400.. / 0x1800..,
sub 1) is valid (bit 31 clear), with the objects of its default mapping (0x1600.. / 0x1A00..). The master writes it
by SDO at every start (a drive's current mapping is never assumed) and packs / unpacks the frames with the `struct`
formats derived here from the mapped objects' data types; PDOs the EDS has but disables are switched off. The
simulated drives build their frames from what the master wrote.

What the master needs: 0x6040 controlword and 0x6071 target torque in the RPDOs (0x60FF target velocity for CSV),
and 0x6041 statusword, 0x6064 position actual, 0x6078 current actual together in one TPDO (a cycle is complete when
that TPDO of every drive is in).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from js2spec.errors import ConfigError

# CiA 301 basic data types -> struct codes (little endian on the wire)
STRUCT_CODE = {0x1: "?", 0x2: "b", 0x3: "h", 0x4: "i", 0x5: "B", 0x6: "H", 0x7: "I"}

CONTROLWORD, TARGET_TORQUE, TARGET_VELOCITY = 0x6040, 0x6071, 0x60FF
STATUSWORD, POSITION_ACTUAL, CURRENT_ACTUAL = 0x6041, 0x6064, 0x6078
FEEDBACK = (STATUSWORD, POSITION_ACTUAL, CURRENT_ACTUAL)


@dataclass(frozen=True)
class Pdo:
    name: str                   # 'RPDO1', 'TPDO1', ...
    comm: int                   # communication parameter index (0x1400.. / 0x1800..)
    mapping: int                # mapping parameter index (0x1600.. / 0x1A00..)
    cob_base: int               # COB-ID minus the node-id
    transmission: int           # 0x14xx/0x18xx sub 2 (1 = every SYNC)
    entries: tuple              # mapping words 0xIIIISSLL, frame order
    objects: tuple              # object indices, frame order
    codec: struct.Struct        # packs / unpacks the frame

    def cob_id(self, node_id: int) -> int:
        return self.cob_base + int(node_id)


@dataclass(frozen=True)
class PdoLayout:
    source: str
    rpdos: tuple                # Pdo, enabled, master -> drive
    tpdos: tuple                # Pdo, enabled, drive -> master
    disabled: tuple             # (comm index, COB-ID base) of PDOs the EDS has but disables
    sync_cob: int               # 0x1005

    @property
    def feedback(self) -> Pdo:
        """The TPDO that carries statusword, position and current."""
        for p in self.tpdos:
            if all(o in p.objects for o in FEEDBACK):
                return p
        raise AssertionError("checked in read_layout")

    def rpdo_with(self, index: int) -> Pdo | None:
        for p in self.rpdos:
            if index in p.objects:
                return p
        return None

    def frame_bytes(self) -> tuple[list[int], list[int]]:
        """Data bytes of each RPDO and TPDO (for the bus-load arithmetic)."""
        return [p.codec.size for p in self.rpdos], [p.codec.size for p in self.tpdos]


def _pdos(od, path, comm0: int, map0: int, kind: str):
    on, off = [], []
    for k in range(512):
        comm, mp = comm0 + k, map0 + k
        if comm not in od:
            break
        cob = int(od[comm][1].default)
        if cob & 0x80000000:
            off.append((comm, (cob & 0x7FF) - 1))
            continue
        n = int(od[mp][0].default)
        entries, objects, codes = [], [], ""
        for s in range(1, n + 1):
            e = int(od[mp][s].default)
            idx, sub = e >> 16, (e >> 8) & 0xFF
            try:
                obj = od[idx] if idx in od and not hasattr(od[idx], "subindices") else od[idx][sub]
            except KeyError:
                raise ConfigError(path, None, f"{kind}{k + 1} maps 0x{idx:04X}:{sub}, which the EDS does not "
                                  f"define; fix 0x{mp:04X} in the EDS") from None
            if obj.data_type not in STRUCT_CODE:
                raise ConfigError(path, None, f"{kind}{k + 1} maps 0x{idx:04X} of data type 0x{obj.data_type:X}; "
                                  f"only 8/16/32-bit integers are supported in cyclic PDOs")
            entries.append(e)
            objects.append(idx)
            codes += STRUCT_CODE[obj.data_type]
        trans = int(od[comm][2].default) if 2 in od[comm] else 1
        on.append(Pdo(f"{kind}{k + 1}", comm, mp, (cob & 0x7FF) - 1, trans, tuple(entries), tuple(objects),
                      struct.Struct("<" + codes)))
    return on, off


@lru_cache(maxsize=8)
def read_layout(eds_path) -> PdoLayout:
    """The PDO layout of the drives described by `eds_path` (node-id 1 resolves $NODEID; COB-IDs are kept relative)."""
    import canopen
    path = str(eds_path)
    if not Path(path).is_file():
        raise ConfigError(path, None, "the drives' EDS is missing; add drives.eds to the robot folder")
    try:
        od = canopen.import_od(path, 1)
    except Exception as e:   # noqa: BLE001 - canopen raises assorted errors for a malformed file
        raise ConfigError(path, None, f"cannot read the EDS ({type(e).__name__}: {e}); fix the file") from None
    rp, rp_off = _pdos(od, path, 0x1400, 0x1600, "RPDO")
    tp, tp_off = _pdos(od, path, 0x1800, 0x1A00, "TPDO")
    for p in rp + tp:
        if p.codec.size > 8:
            raise ConfigError(path, None, f"{p.name} maps {p.codec.size} bytes; a CAN frame holds 8")
    if not any(CONTROLWORD in p.objects for p in rp) or not any(TARGET_TORQUE in p.objects for p in rp):
        raise ConfigError(path, None, "no default RPDO maps 0x6040 (controlword) and 0x6071 (target torque); "
                          "map them in 0x1600.. of the EDS")
    if not any(all(o in p.objects for o in FEEDBACK) for p in tp):
        raise ConfigError(path, None, "no default TPDO maps 0x6041, 0x6064 and 0x6078 together; map them in one of "
                          "0x1A00.. of the EDS")
    sync = int(od[0x1005].default) & 0x7FF if 0x1005 in od else 0x80
    return PdoLayout(path, tuple(rp), tuple(tp), tuple(rp_off + tp_off), sync)
