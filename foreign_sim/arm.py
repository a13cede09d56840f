"""The true Staubli TX40 of one bench: perturbed URDF inertials, perturbed friction priors, transmission.

Its physics is independent of the rest of the project (it reads data only): kinematics from ``tx40.urdf`` (a copy of FIGAROH's
``tx40_mdh_modified.urdf``), transmission from the TX40's one drives file (identification/examples/staubli_tx40/
drives.yaml, data, not code: the arm's gear matrix and offsets as FIGAROH converts them), friction priors from
FIGAROH's published ``TX40_config.yaml`` (joint side, converted to the motor side here).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

HERE = Path(__file__).resolve().parent
URDF = HERE / "tx40.urdf"
DRIVES = HERE.parent / "identification" / "examples" / "staubli_tx40" / "drives.yaml"
NJ = 6

# FIGAROH TX40_config.yaml (identification.robot_params), JOINT side
PRIOR_FV = np.array([8.05, 5.53, 1.97, 1.11, 1.86, 0.65])        # N*m*s/rad
PRIOR_FS = np.array([7.14, 8.26, 6.34, 2.48, 3.03, 0.282])       # N*m (Coulomb level)
PRIOR_IA = np.array([0.362, 0.362, 0.0988, 0.0313, 0.0468, 0.0105])  # kg*m^2 (reflected rotor inertia)
REDUCTION = np.array([32.0, 32.0, 45.0, -48.0, 45.0, 32.0])

# a sensible joint range (rad): centre and half range (the URDF limits, joints 2 and 3 narrower); use +-80 %
Q_CENTER = np.array([0.0, 0.0, 0.0, 0.0, 0.1, 0.0])
Q_HALF = np.array([2.6, 1.3, 1.5, 3.0, 1.7, 3.0])
G = 9.81


def load_drives(path: Path = DRIVES):
    d = yaml.safe_load(Path(path).read_text())
    K = np.asarray(d["gear_ratio_matrix"], float)
    off = np.asarray(d["joint_offset"], float)
    return K, off, list(d["joints"])


def nominal_model():
    model = pin.buildModelFromUrdf(str(URDF))
    model.gravity.linear = np.array([0.0, 0.0, -G])
    return model


def nominal_friction():
    """Motor-side priors: B = fv/N^2, f_c = fs/|N|, J_a = Ia/N^2 (f_s = f_c nominally: the model has no stiction)."""
    N = REDUCTION
    return dict(B=PRIOR_FV / N ** 2, fc=PRIOR_FS / np.abs(N), Ja=PRIOR_IA / N ** 2)


def _perturb_inertia(I: pin.Inertia, rng) -> pin.Inertia:
    """Scale mass, shift the COM slightly, scale the rotational inertia (about the COM): stays physical."""
    m = I.mass * (1.0 + rng.uniform(-0.1, 0.1))
    c = np.array(I.lever) * (1.0 + rng.uniform(-0.1, 0.1, 3)) + rng.uniform(-0.005, 0.005, 3)
    Ic = np.array(I.inertia)
    s = 1.0 + rng.uniform(-0.1, 0.1, 3)
    D = np.diag(np.sqrt(s))
    Ic = D @ Ic @ D            # congruence keeps it positive semi-definite
    Ic = 0.5 * (Ic + Ic.T)
    return pin.Inertia(m, c, Ic)


class TrueArm:
    """The concealed truth of a bench: ``model``/``data`` (perturbed inertials), motor-side friction arrays
    ``B``, ``fc``, ``fs`` (breakaway), rotor inertia ``Ja``, transmission ``K`` and ``offset`` (drives.yaml), and the
    nominal model/friction the users get (``nom_model``, ``nom``)."""

    def __init__(self, arm_seed: int = 0):
        self.arm_seed = int(arm_seed)
        rng = np.random.default_rng(np.random.SeedSequence([0x7A40, self.arm_seed]))
        self.K, self.offset, self.joint_names = load_drives()
        self.Kinv = np.linalg.inv(self.K)
        self.nom_model = nominal_model()
        self.nom_data = self.nom_model.createData()
        self.nom = nominal_friction()
        self.model = nominal_model()
        for jid in range(1, self.model.njoints):
            self.model.inertias[jid] = _perturb_inertia(self.model.inertias[jid], rng)
        self.data = self.model.createData()
        f = 1.0 + rng.uniform(-0.15, 0.15, (3, NJ))
        self.B = self.nom["B"] * f[0]
        self.fc = self.nom["fc"] * f[1]
        self.Ja = self.nom["Ja"] * f[2]
        self.fs = self.fc * rng.uniform(1.2, 1.6, NJ)
        # torque saturation per motor: 3 x (gravity scale + breakaway + inertial and viscous scales)
        self.gravity_scale = self._gravity_scale(rng)
        Mm = self.K.T @ pin.crba(self.nom_model, self.nom_data, Q_CENTER.copy()) @ self.K + np.diag(self.nom["Ja"])
        self.inertial_scale = np.diag(Mm) * 400.0            # 400 rad/s^2 at the motor
        self.viscous_scale = self.nom["B"] * 100.0            # 100 rad/s at the motor
        self.tau_sat = 3.0 * (self.gravity_scale + self.fs + self.inertial_scale + self.viscous_scale)

    def _gravity_scale(self, rng):
        r = np.random.default_rng(1)
        gs = np.zeros(NJ)
        for _ in range(200):
            q = Q_CENTER + 0.8 * Q_HALF * r.uniform(-1, 1, NJ)
            gs = np.maximum(gs, np.abs(self.K.T @ pin.computeGeneralizedGravity(self.nom_model, self.nom_data, q)))
        return gs

    def inertials(self, model=None):
        model = model or self.model
        out = {}
        for jid in range(1, model.njoints):
            I = model.inertias[jid]
            out[model.names[jid]] = dict(mass=float(I.mass), com=np.array(I.lever).tolist(),
                                         inertia_about_com=np.array(I.inertia).tolist())
        return out

    def truth_dict(self):
        return dict(arm_seed=self.arm_seed,
                    friction_motor_side=dict(viscous=self.B.tolist(), coulomb=self.fc.tolist(),
                                             breakaway=self.fs.tolist(), rotor_inertia=self.Ja.tolist()),
                    nominal_friction_motor_side={k: v.tolist() for k, v in self.nom.items()},
                    torque_saturation=self.tau_sat.tolist(),
                    gear_ratio_matrix=self.K.tolist(), joint_offset=self.offset.tolist(),
                    inertials=self.inertials())
