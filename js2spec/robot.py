"""A robot described as data: one ``configs/<robot>/`` folder.

| file | what |
| --- | --- |
| ``robot.urdf`` | kinematics and nominal inertial parameters |
| ``drives.yaml`` | drive and transmission data (:mod:`js2spec.drives`) |
| ``drives.eds`` | the drives' CANopen object dictionary (acquisition, simulated drives) — optional |
| ``trials.yaml`` | trial settings for acquisition — optional |
| ``sim_truth.yaml`` | the simulator's true parameters (hil_sim only) — optional |

Porting js2 to another arm means writing such a folder, not code.
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .drives import DrivesConfig, load_drives
from .errors import ConfigError
from .files import read_text

#: The folder of robot configs shipped with js2 (``<repo>/configs``).
BUILTIN_CONFIGS = Path(__file__).resolve().parents[1] / "configs"


@dataclass(frozen=True, eq=False)
class RobotConfig:
    name: str
    folder: Path
    urdf_path: Path
    urdf_text: str
    drives: DrivesConfig
    sim_truth_path: Path | None
    trials_path: Path | None
    eds_path: Path | None

    @property
    def drives_yaml(self) -> str:
        return read_text(self.folder / "drives.yaml", "drives.yaml")


def config_search_path() -> list[Path]:
    """Where robot names are looked up: ``$JS2_CONFIG_PATH`` (os.pathsep-separated), then the built-in configs."""
    extra = [Path(p) for p in os.environ.get("JS2_CONFIG_PATH", "").split(os.pathsep) if p]
    return extra + [BUILTIN_CONFIGS]


def available_robots() -> list[str]:
    names = set()
    for base in config_search_path():
        if base.is_dir():
            names.update(p.name for p in base.iterdir() if (p / "drives.yaml").is_file())
    return sorted(names)


def resolve_robot_folder(name_or_path: str | Path) -> Path:
    p = Path(name_or_path)
    if p.is_dir():
        return p
    if p.suffix in (".yaml", ".urdf") and p.is_file():
        return p.parent
    for base in config_search_path():
        if (base / str(name_or_path)).is_dir():
            return base / str(name_or_path)
    known = ", ".join(available_robots()) or "none"
    raise ConfigError(name_or_path, None,
                      f"unknown robot (not a folder, not in {', '.join(map(str, config_search_path()))}); "
                      f"known robots: {known}")


def check_urdf(urdf_text: str, source: str | Path, joints: list[str] | None = None) -> list[str]:
    """Check a URDF for what identification and simulation need; return its actuated joint names in file order.

    Refuses: not XML, no revolute/prismatic joints, non-positive masses, inertias that are not positive definite
    or break the triangle inequalities, and (when ``joints`` is given) drive joints that the URDF lacks or
    actuated URDF joints that no drive moves.
    """
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as exc:
        raise ConfigError(source, None, f"is not valid URDF/XML ({exc})") from None
    if root.tag != "robot":
        raise ConfigError(source, None, f"root element is <{root.tag}>, expected <robot>")
    actuated = [j.get("name") for j in root.iter("joint")
                if j.get("type") in ("revolute", "continuous", "prismatic")]
    if not actuated:
        raise ConfigError(source, None, "has no revolute, continuous or prismatic joint")
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        lname = link.get("name")
        mass_el = inertial.find("mass")
        if mass_el is None:
            raise ConfigError(source, f"link[{lname}].inertial.mass", "missing")
        try:
            mass = float(mass_el.get("value"))
        except (TypeError, ValueError):
            raise ConfigError(source, f"link[{lname}].inertial.mass", "is not a number") from None
        if not mass > 0 and not (mass == 0 and lname in ("world", "base_link", "base")):
            raise ConfigError(source, f"link[{lname}].inertial.mass", f"must be > 0, got {mass}")
        inertia_el = inertial.find("inertia")
        if inertia_el is None or mass == 0:
            continue
        try:
            ixx, ixy, ixz, iyy, iyz, izz = (float(inertia_el.get(k)) for k in
                                            ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
        except (TypeError, ValueError):
            raise ConfigError(source, f"link[{lname}].inertial.inertia", "needs numeric ixx..izz") from None
        inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        eig = np.linalg.eigvalsh(inertia)
        if eig[0] <= 0:
            raise ConfigError(source, f"link[{lname}].inertial.inertia",
                              f"is not positive definite (eigenvalues {np.round(eig, 9).tolist()})")
        p = np.sort(eig)
        if p[0] + p[1] < p[2] * (1 - 1e-9):
            raise ConfigError(source, f"link[{lname}].inertial.inertia",
                              "breaks the triangle inequality of principal moments (not a physical body)")
    if joints is not None:
        missing = [j for j in joints if j not in actuated]
        if missing:
            raise ConfigError(source, "joint",
                              f"drives.yaml names joints the URDF does not have as actuated joints: {missing} "
                              f"(URDF has {actuated})")
        extra = [j for j in actuated if j not in joints]
        if extra:
            raise ConfigError(source, "joint",
                              f"URDF joints {extra} are moved by no drive in drives.yaml (joints: {joints})")
    return actuated


# Objects of the drives' dictionary that the master (js2io) and the simulated drives (hil_sim) both use.
EDS_REQUIRED = (0x1017, 0x1400, 0x1600, 0x1800, 0x1A00, 0x6040, 0x6041, 0x6060, 0x6061, 0x6064, 0x6071, 0x6072)


def check_eds(path: Path) -> None:
    """The drives' EDS parses (canopen's own importer) and has the CiA 301/402 objects js2 uses."""
    import canopen
    try:
        od = canopen.import_od(str(path))
    except Exception as e:   # noqa: BLE001 - configparser / canopen raise many kinds; all mean 'not an EDS'
        msg = " ".join(str(e).split())[:120]
        raise ConfigError(path, None, f"is not a readable EDS ({type(e).__name__}: {msg}); use the drive "
                                      f"vendor's EDS file") from None
    missing = [f"0x{i:04X}" for i in EDS_REQUIRED if i not in od]
    if missing:
        raise ConfigError(path, None, f"lacks the objects {', '.join(missing)} that js2 needs (CiA 301/402); "
                                      f"is it the EDS of a CiA 402 drive?")


def load_robot(name_or_path: str | Path) -> RobotConfig:
    """Load and validate ``configs/<name>/`` (or any folder with the same files)."""
    folder = resolve_robot_folder(name_or_path)
    urdf_path = folder / "robot.urdf"
    if not urdf_path.is_file():
        urdfs = sorted(folder.glob("*.urdf"))
        if len(urdfs) != 1:
            raise ConfigError(urdf_path, None, "file not found (a robot folder needs robot.urdf)")
        urdf_path = urdfs[0]
    drives = load_drives(folder / "drives.yaml")
    urdf_text = read_text(urdf_path, "URDF")
    check_urdf(urdf_text, urdf_path, drives.joints)

    def opt(name):
        p = folder / name
        if not p.exists():
            return None
        read_text(p, name)       # refused now, in one line, rather than mid-session (EDS, trials, simulator truth)
        return p

    eds = opt("drives.eds")
    if eds is not None:
        check_eds(eds)

    return RobotConfig(name=folder.name, folder=folder, urdf_path=urdf_path, urdf_text=urdf_text, drives=drives,
                       sim_truth_path=opt("sim_truth.yaml"), trials_path=opt("trials.yaml"),
                       eds_path=eds)
