"""control.py: the hand-designed half of the hybrid policy (paper Sec. 4.1), pure numpy.

    Eq. 3-5  Cartesian admittance (parallel position/force) control -> joint velocities
    Eq. 6    hybrid policy  q_dot = f_c(tau(t), K, pi(s)), the residual action being F_d
    Eq. 7-9  stiffness from the deviation workspace:  K = 1/2 F_max diag(W)^-1,  W = E_r + (X^_i - X^_g)
    tau(t)   the linear trajectory from the estimated pre-assembly point X^_i to the estimated goal X^_g

Nothing here knows about pybullet: poses are (p, R) pairs of a position (3,) in m and a rotation
matrix (3, 3), wrenches are 6-vectors (N, N m), all in one frame chosen by the caller (tacrl's sim
uses world axes at the tool tip). Sign convention, as in Eq. 4: F is the wrench the environment
exerts on the tool (what the wrist sensor reads), F_d the reading we ask for; in free space the
tool settles at X = X_d - K^-1 F_d, against a wall the reading settles at F = F_d - K (X_d - X) (Eq. 7).

Symbols: x_d = X_d, f = F, f_d = F_d, m/b/k = diagonals of M/B/K, w = W, e_r = E_r.
"""
from dataclasses import dataclass, field

import numpy as np


# ---------------------------------------------------------------- rotations (so/3 <-> SO(3))
def skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rotvec_to_matrix(r):
    """Rodrigues: rotation vector (3,) rad -> rotation matrix (3, 3)."""
    th = np.linalg.norm(r)
    if th < 1e-12:
        return np.eye(3) + skew(r)
    k = skew(np.asarray(r) / th)
    return np.eye(3) + np.sin(th) * k + (1.0 - np.cos(th)) * (k @ k)


def matrix_to_rotvec(R):
    """Log map: rotation matrix (3, 3) -> rotation vector (3,) rad, valid up to angles near pi."""
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    th = np.arccos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-6:
        return 0.5 * w
    return th / (2.0 * np.sin(th)) * w


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def pose_error(x_d, x):
    """X_d - X as a 6-vector: position difference (m) and the rotation vector of R_d R^T (rad),
    both in the frame the poses are given in."""
    (p_d, R_d), (p, R) = x_d, x
    return np.concatenate([p_d - p, matrix_to_rotvec(R_d @ R.T)])


# ---------------------------------------------------------------- Eq. 7-9: stiffness
def workspace(ex_r, x_i_hat, x_g_hat):
    """Eq. 8: W = E_r + |X^_i - X^_g| per axis (6,). ex_r is the exploration range per axis (6,):
    the paper's E_r in Eq. 8, which the curriculum sets apart from the guidance error (Ex_r)."""
    return np.asarray(ex_r, float) + np.abs(pose_error(x_i_hat, x_g_hat))


def stiffness(f_max, w):
    """Eq. 9: K = 1/2 F_max diag(W)^-1. f_max (6,) is the contact safety limit per axis (N, N m):
    a residual F_d within +-F_max/2 can then move the tool anywhere inside W (Eq. 7)."""
    return 0.5 * np.asarray(f_max, float) / np.asarray(w, float)


def critical_damping(k, m, zeta=1.0):
    """B = 2 zeta sqrt(K M) per axis: zeta >= 1 gives a step response without overshoot."""
    return 2.0 * zeta * np.sqrt(np.asarray(k) * np.asarray(m))


# ---------------------------------------------------------------- Eq. 3-5: admittance law
@dataclass
class Admittance:
    """Eq. 5, q_dot = J^-1 M^-1 / (s + M^-1 B) [K (X_d - X) - (F_d - F)], discretised at rate 1/dt.

    The first-order filter M^-1/(s + M^-1 B) is stepped with its exact zero-order-hold solution,
    so it is stable for any dt; the returned Cartesian velocity V (6,) is mapped to joints by
    `joint_velocities`. Diagonal M, B, K (6,) each.
    """
    m: np.ndarray
    b: np.ndarray
    k: np.ndarray
    dt: float = 1.0 / 120.0
    v: np.ndarray = field(default_factory=lambda: np.zeros(6))

    def reset(self):
        self.v = np.zeros(6)

    def step(self, err, f, f_d):
        """err = X_d - X (6,), f = measured wrench F (6,), f_d = desired wrench F_d (6,) -> V (6,)."""
        u = self.k * err - (np.asarray(f_d) - np.asarray(f))   # Eq. 5: the bracket, a force
        a = np.exp(-self.dt * self.b / self.m)                  # Eq. 5: M^-1/(s + M^-1 B), ZOH
        self.v = a * self.v + (1.0 - a) * u / self.b
        return self.v


def joint_velocities(jac, v, damping=1e-3):
    """Eq. 5: q_dot = J^-1 V, as damped least squares J^T (J J^T + lambda^2 I)^-1 V so that a
    singular pose gives a bounded command. jac (6, n), v (6,) -> (n,)."""
    jj = jac @ jac.T + damping ** 2 * np.eye(jac.shape[0])
    return jac.T @ np.linalg.solve(jj, v)


# ---------------------------------------------------------------- the trajectory tau(t)
def linear_trajectory(x_i, x_g, t, duration, rv=None):
    """tau(t): straight line from X^_i to X^_g in `duration` s (position lerp, rotation slerp),
    then holds X^_g. Returns X_d = (p, R). rv: the rotation vector of R_i^T R_g, if precomputed."""
    s = min(max(t / duration, 0.0), 1.0)
    (p_i, R_i), (p_g, R_g) = x_i, x_g
    if rv is None:
        rv = matrix_to_rotvec(R_i.T @ R_g)
    return p_i + s * (p_g - p_i), R_i @ rotvec_to_matrix(s * rv)


# ---------------------------------------------------------------- Eq. 6: the hybrid policy
@dataclass
class HybridPolicy:
    """Eq. 6: q_dot = f_c(tau(t), K, pi(s)). The hand-designed part pi_h(t) is the trajectory
    tau(t) from X^_i to X^_g and the stiffness K of Eq. 9; the residual pi(s) supplies F_d (Eq. 12).

    x_i_hat, x_g_hat: estimated pre-assembly and goal poses (p, R); ex_r (6,): exploration range;
    f_max (6,): contact safety limit; m (6,): virtual mass; duration: s from X^_i to X^_g (inf:
    X_d stays at X^_i, no trajectory guidance); zeta: damping ratio of the compliance.
    b_free (6,): no hand-designed part at all (the vanilla baseline): K = 0, so no spring pulls toward
    tau(t) or X^_i, and this fixed damping B, so that F_d alone moves the tool (V = (F - F_d) / B in
    steady state); W (Eq. 8) is still computed, for the reward's weights.
    """
    x_i_hat: tuple
    x_g_hat: tuple
    ex_r: np.ndarray
    f_max: np.ndarray
    m: np.ndarray
    duration: float
    zeta: float = 1.0
    dt: float = 1.0 / 120.0
    b_free: np.ndarray = None

    def __post_init__(self):
        self.w = workspace(self.ex_r, self.x_i_hat, self.x_g_hat)        # Eq. 8
        m = np.asarray(self.m, float)
        if self.b_free is None:
            k = stiffness(self.f_max, self.w)                             # Eq. 9
            self.adm = Admittance(m, critical_damping(k, m, self.zeta), k, self.dt)
        else:                                                             # no base policy: a free admittance
            self.adm = Admittance(m, np.asarray(self.b_free, float), np.zeros(6), self.dt)
        self._rv = matrix_to_rotvec(self.x_i_hat[1].T @ self.x_g_hat[1])

    def x_d(self, t):
        return linear_trajectory(self.x_i_hat, self.x_g_hat, t, self.duration, self._rv)

    def __call__(self, t, x, f, f_d, jac):
        """One control tick: time t (s), tool pose X, wrench F (6,), residual F_d (6,), Jacobian (6, n)
        -> joint velocities (n,)."""
        v = self.adm.step(pose_error(self.x_d(t), x), f, f_d)
        return joint_velocities(jac, v)
