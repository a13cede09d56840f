"""The identification model of eq. 1, linear in its parameters, on the side where torque is measured.

Eq. 1 (motor side), with theta = K theta_m + offset (so K^-1 theta_d = theta_m_d):

    tau_m = K^T (M(theta) theta_dd + h(theta, theta_d) theta_d + g(theta))
            + J_a theta_m_dd + B theta_m_d + f_c sgn(theta_m_d)

The rigid-body part is linear in the ten standard inertial parameters of each body (pinocchio's
``computeJointTorqueRegressor``: ``tau_joint = Y(q, dq, ddq) pi``), so

    tau_m = [ K^T Y | diag(theta_m_dd) | diag(theta_m_d) | diag(sgn theta_m_d) ] [pi; J_a; B; f_c]

One sample gives an (n x p) block; stacking samples gives the observation matrix used by every estimator.
When the log's torques are joint-side (``torque_side: joint``, torque sensors behind the gears), the K^T mapping is
left out and the "motor" columns become per-joint armature / viscous / Coulomb terms on the joint velocity.

Standard parameter names (per body ``<link>``, pinocchio's order, inertia about the joint frame origin):
``m_<link>, mx_<link>, my_<link>, mz_<link>, Ixx_<link>, Ixy_<link>, Iyy_<link>, Ixz_<link>, Iyz_<link>, Izz_<link>``,
then ``Ja_<k>`` (motor inertia, kg m^2), ``B_<k>`` (viscous, N m s/rad), ``fc_<k>`` (Coulomb, N m), optionally
``off_<k>`` (constant torque offset, N m) and ``Bs_<k>`` (square-root viscous friction ``Bs sgn(v) sqrt|v|``,
N m (s/rad)^0.5, a velocity-dependent friction that grows less than linearly, e.g. in gears), with k the 1-based
drive number.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from js2spec.errors import ConfigError

INERTIAL_NAMES = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
_AXIS_INERTIA = {0: "Ixx", 1: "Iyy", 2: "Izz"}


@dataclass
class ArmModel:
    """Kinematics (pinocchio, from the URDF) + transmission (K, offsets) of one arm, in drive order.

    Built with :func:`arm_model`. ``joint_ids[i]`` is the pinocchio joint index of ``drives.joints[i]``;
    ``perm`` maps pinocchio's velocity order to drive order (``q_pin[perm] = q_drive`` is NOT used: we
    always fill pinocchio vectors with ``q_pin[idx_v[i]] = q_drive[i]``).
    """

    model: pin.Model
    joints: list[str]
    links: list[str]
    K: np.ndarray
    joint_offset: np.ndarray
    torque_side: str
    idx_v: np.ndarray
    axis_local: np.ndarray
    urdf_text: str = ""
    nominal_inertial: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def Kinv(self) -> np.ndarray:
        return np.linalg.inv(self.K)

    def joint_from_motor(self, q_motor: np.ndarray) -> np.ndarray:
        """theta = K theta_m + offset, row-wise for (N, n) arrays."""
        return q_motor @ self.K.T + self.joint_offset

    def axis_inertia_name(self, i: int) -> str:
        """Standard-parameter name of body i's inertia about its own joint axis (the paper's J_iz)."""
        ax = np.abs(self.axis_local[i])
        k = int(np.argmax(ax))
        return f"{_AXIS_INERTIA[k]}_{self.links[i]}"


def arm_model(urdf_text: str, drives, urdf_name: str = "robot.urdf") -> ArmModel:
    """Build the :class:`ArmModel` from URDF text and a ``js2spec.drives.DrivesConfig``.

    Raises ConfigError (naming the file) if the URDF's moving joints are not exactly ``drives.joints``, or a joint is
    not a 1-DOF revolute/prismatic joint.
    """
    import re

    # <dynamics> (damping/friction) is not used here (friction is identified) and pinocchio refuses some published
    # values (negative friction), so it is stripped before parsing
    try:
        model = pin.buildModelFromXML(re.sub(r"<dynamics\b[^>]*/>", "", urdf_text))
    except Exception as exc:  # pinocchio raises RuntimeError/ValueError with its own text
        raise ConfigError(urdf_name, None, f"not a URDF pinocchio can read ({exc})") from None
    names = [model.names[i] for i in range(1, model.njoints)]
    joints = list(drives.joints)
    if sorted(names) != sorted(joints):
        raise ConfigError(
            urdf_name, "joints",
            f"URDF moving joints {names} do not match drives.yaml joints {joints}")
    idx_v, links, axes = [], [], []
    for jn in joints:
        jid = model.getJointId(jn)
        jm = model.joints[jid]
        if jm.nq != 1 or jm.nv != 1:
            raise ConfigError(urdf_name, jn, f"joint type {jm.shortname()} is not a 1-DOF revolute/prismatic joint")
        idx_v.append(jm.idx_v)
        # the child body of joint jid: first frame of type BODY whose parentJoint is jid
        child = next((f.name for f in model.frames if f.parentJoint == jid and f.type == pin.FrameType.BODY),
                     f"body{jid}")
        links.append(child)
        ax = _joint_axis(model, jid)  # axis in the joint frame
        axes.append(ax)
    K = np.asarray(drives.gear_ratio_matrix, dtype=float)
    off = np.asarray(drives.joint_offset if drives.joint_offset is not None else np.zeros(len(joints)), dtype=float)
    nominal = np.concatenate([
        np.asarray(model.inertias[model.getJointId(jn)].toDynamicParameters()) for jn in joints])
    return ArmModel(model=model, joints=joints, links=links, K=K, joint_offset=off,
                    torque_side=str(getattr(drives, "torque_side", "motor")), idx_v=np.asarray(idx_v),
                    axis_local=np.asarray(axes), urdf_text=urdf_text, nominal_inertial=nominal)


def _joint_axis(model: pin.Model, jid: int) -> np.ndarray:
    """Unit axis of a 1-DOF joint in its own frame (angular part for revolute, linear for prismatic)."""
    data = model.createData()
    q = pin.neutral(model)
    v = np.zeros(model.nv)
    v[model.joints[jid].idx_v] = 1.0
    pin.forwardKinematics(model, data, q, v)
    vel = data.v[jid]
    w = np.asarray(vel.angular)
    if np.linalg.norm(w) > 1e-9:
        return w / np.linalg.norm(w)
    lin = np.asarray(vel.linear)
    return lin / max(np.linalg.norm(lin), 1e-12)


def standard_names(arm: ArmModel, offsets: bool = False, sqrt_viscous: bool = False) -> list[str]:
    """Names of the standard parameter vector's columns (see module docstring)."""
    names = [f"{p}_{lk}" for lk in arm.links for p in INERTIAL_NAMES]
    n = arm.n
    names += [f"Ja_{k + 1}" for k in range(n)]
    names += [f"B_{k + 1}" for k in range(n)]
    names += [f"fc_{k + 1}" for k in range(n)]
    if offsets:
        names += [f"off_{k + 1}" for k in range(n)]
    if sqrt_viscous:
        names += [f"Bs_{k + 1}" for k in range(n)]
    return names


def column_groups(arm: ArmModel, offsets: bool = False, sqrt_viscous: bool = False) -> dict[str, np.ndarray]:
    """Indices of the column groups: ``inertial`` (links), ``motor`` (J_a), ``viscous``, ``coulomb``, ``offset``,
    ``sqrt_viscous``."""
    n, nl = arm.n, 10 * arm.n
    g = {"inertial": np.arange(nl), "motor": np.arange(nl, nl + n), "viscous": np.arange(nl + n, nl + 2 * n),
         "coulomb": np.arange(nl + 2 * n, nl + 3 * n)}
    g["offset"] = np.arange(nl + 3 * n, nl + 4 * n) if offsets else np.arange(0)
    k0 = nl + (4 if offsets else 3) * n
    g["sqrt_viscous"] = np.arange(k0, k0 + n) if sqrt_viscous else np.arange(0)
    return g


def rigid_body_regressor(arm: ArmModel, q_joint: np.ndarray, dq_joint: np.ndarray, ddq_joint: np.ndarray,
                         progress=None) -> np.ndarray:
    """Joint-side rigid-body regressor Y, shape (N, n, 10 n), drive order: ``tau_joint[s] = Y[s] @ pi``.

    One ``pinocchio.computeJointTorqueRegressor`` call per sample (the C++ is ~2 us per call; the Python loop is the
    cost, kept minimal: preallocated arrays, no per-sample allocations beyond pinocchio's return view).
    """
    N, n = q_joint.shape
    model, data = arm.model, arm.model.createData()
    nv = model.nv
    # pinocchio order <-> drive order
    pin_of_drive = arm.idx_v
    q = np.zeros((N, model.nq))
    v = np.zeros((N, nv))
    a = np.zeros((N, nv))
    q[:, pin_of_drive] = q_joint  # nq == nv for 1-DOF joints
    v[:, pin_of_drive] = dq_joint
    a[:, pin_of_drive] = ddq_joint
    # body blocks: pinocchio's columns are ordered by joint index; map to drive order
    jids = np.array([arm.model.getJointId(j) for j in arm.joints])
    col_perm = np.concatenate([np.arange(10) + 10 * (jid - 1) for jid in jids])
    out = np.empty((N, n, 10 * n))
    reg = pin.computeJointTorqueRegressor
    it = range(N) if progress is None else progress(range(N))
    identity = (np.array_equal(pin_of_drive, np.arange(n)) and np.array_equal(col_perm, np.arange(10 * n))
                and nv == n)
    if identity:          # URDF order == drive order: copy pinocchio's result as it is
        for s in it:
            out[s] = reg(model, data, q[s], v[s], a[s])
    else:
        for s in it:
            Y = reg(model, data, q[s], v[s], a[s])
            out[s] = Y[pin_of_drive][:, col_perm]
    return out


def build_regressor(arm: ArmModel, q_motor: np.ndarray, dq_motor: np.ndarray, ddq_motor: np.ndarray,
                    offsets: bool = False, velocity_for_sign: np.ndarray | None = None,
                    progress=None, chunk: int = 1024, sqrt_viscous: bool = False) -> np.ndarray:
    """Full observation block per sample (eq. 1), shape (N, n, p), on the log's torque side.

    Motor side (``torque_side: motor``): ``[K^T Y(theta) | diag(theta_m_dd) | diag(theta_m_d) | diag(sgn theta_m_d)]``.
    Joint side: ``[Y(theta) | diag(theta_dd) | diag(theta_d) | diag(sgn theta_d)]``.
    ``velocity_for_sign`` (motor rad/s, default ``dq_motor``) is what the Coulomb column takes the sign of.
    Computed ``chunk`` samples at a time (cache-sized temporaries: ~1.5x faster than one big pass).
    """
    N = len(q_motor)
    if N > chunk:
        n = q_motor.shape[1]
        p = 10 * n + 3 * n + (n if offsets else 0) + (n if sqrt_viscous else 0)
        out = np.empty((N, n, p))
        for c0 in range(0, N, chunk):
            c1 = min(c0 + chunk, N)
            out[c0:c1] = build_regressor(arm, q_motor[c0:c1], dq_motor[c0:c1], ddq_motor[c0:c1], offsets,
                                         None if velocity_for_sign is None else velocity_for_sign[c0:c1],
                                         None, chunk, sqrt_viscous)
        return out
    K = arm.K
    q_joint = arm.joint_from_motor(q_motor)
    dq_joint = dq_motor @ K.T
    ddq_joint = ddq_motor @ K.T
    Y = rigid_body_regressor(arm, q_joint, dq_joint, ddq_joint, progress=progress)
    N, n = q_motor.shape
    p = 10 * n + 3 * n + (n if offsets else 0) + (n if sqrt_viscous else 0)
    W = np.empty((N, n, p))
    W[:, :, 10 * n:] = 0.0
    if arm.torque_side == "joint":
        W[:, :, :10 * n] = Y
        dd, d = ddq_joint, dq_joint
        vs = d if velocity_for_sign is None else velocity_for_sign @ K.T
    else:
        np.matmul(K.T, Y, out=W[:, :, :10 * n])  # K^T Y, batched over samples
        dd, d = ddq_motor, dq_motor
        vs = d if velocity_for_sign is None else velocity_for_sign
    idx = np.arange(n)
    W[:, idx, 10 * n + idx] = dd
    W[:, idx, 11 * n + idx] = d
    W[:, idx, 12 * n + idx] = np.sign(vs)
    if offsets:
        W[:, idx, 13 * n + idx] = 1.0
    if sqrt_viscous:
        W[:, idx, (14 if offsets else 13) * n + idx] = np.sign(d) * np.sqrt(np.abs(d))
    return W


def standard_vector(arm: ArmModel, inertial: np.ndarray | None = None, motor_inertia=None, viscous=None,
                    coulomb=None, offset=None, offsets: bool = False, sqrt_viscous: bool = False) -> np.ndarray:
    """Assemble a standard parameter vector (default inertial: the URDF's nominal values; others 0)."""
    n = arm.n
    z = np.zeros(n)
    parts = [arm.nominal_inertial if inertial is None else np.asarray(inertial, float),
             z if motor_inertia is None else np.asarray(motor_inertia, float),
             z if viscous is None else np.asarray(viscous, float),
             z if coulomb is None else np.asarray(coulomb, float)]
    if offsets:
        parts.append(z if offset is None else np.asarray(offset, float))
    if sqrt_viscous:
        parts.append(z)
    return np.concatenate(parts)
