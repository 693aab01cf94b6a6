"""control.py on a simulated point mass (no pybullet): the admittance law of Eq. 5 closed around
an ideal velocity-tracking robot, x_{k+1} = x_k + v dt."""
import numpy as np

import control as ctl

DT = 1.0 / 120.0
M = np.array([20.0, 20.0, 20.0, 0.4, 0.4, 0.4])
K = ctl.stiffness([10.0] * 3 + [1.0] * 3, [0.02, 0.01, 0.06, 0.02, 0.02, 0.1])   # Eq. 9


def run(x_d, f_d, seconds, wall=None, k_wall=2e4):
    """Point mass under the admittance law; optional rigid-ish wall at x[0] = wall (spring k_wall)."""
    adm = ctl.Admittance(M, ctl.critical_damping(K, M), K, DT)
    x, xs, fs = np.zeros(6), [], []
    for _ in range(int(seconds / DT)):
        f = np.zeros(6)
        if wall is not None and x[0] > wall:
            f[0] = -k_wall * (x[0] - wall)          # the wall pushes back (F: environment on tool)
        v = adm.step(x_d - x, f, f_d)
        x = x + v * DT
        xs.append(x.copy())
        fs.append(f.copy())
    return np.array(xs), np.array(fs)


def test_stiffness_eq9():
    w = np.array([0.02, 0.01, 0.06, 0.02, 0.02, 0.1])
    k = ctl.stiffness([10.0] * 3 + [1.0] * 3, w)
    np.testing.assert_allclose(k * w, [5.0] * 3 + [0.5] * 3)      # half F_max spans W


def test_workspace_eq8():
    x_i = (np.array([0.0, 0.0, 0.055]), np.eye(3))
    x_g = (np.zeros(3), np.eye(3))
    np.testing.assert_allclose(ctl.workspace([0.01] * 6, x_i, x_g), [0.01, 0.01, 0.065, 0.01, 0.01, 0.01])


def test_free_space_offset_is_fd_over_k():
    f_d = np.array([3.0, -2.0, 4.0, 0.2, -0.1, 0.3])
    xs, _ = run(np.zeros(6), f_d, 20.0)
    offset = xs[-1]
    expected = -f_d / K                      # Eq. 7 with F = 0: X - X_d = -K^-1 F_d
    np.testing.assert_allclose(offset, expected, rtol=0.02)


def test_step_settles_without_overshoot():
    step = np.array([0.01, -0.01, 0.02, 0.05, -0.05, 0.1])
    xs, _ = run(step, np.zeros(6), 10.0)
    np.testing.assert_allclose(xs[-1], step, rtol=1e-3)
    overshoot = np.max(xs / step, axis=0) - 1.0
    assert np.all(overshoot < 0.01), overshoot          # stated bound: < 1 % of the step (zeta = 1)


def test_wall_force_settles_where_eq7_says():
    # X_d 5 mm beyond a wall at 1 mm, F_d pushing away from it: F = F_d - K (X_d - X)  (Eq. 7)
    x_d = np.array([0.006, 0, 0, 0, 0, 0])
    f_d = np.array([1.0, 0, 0, 0, 0, 0])
    xs, fs = run(x_d, f_d, 20.0, wall=0.001)
    x, f = xs[-1], fs[-1]
    expected = f_d[0] - K[0] * (x_d[0] - x[0])
    assert abs(f[0] - expected) < 0.02 * abs(expected), (f[0], expected)
    assert x[0] > 0.001                                  # it does press into the wall


def test_rotations_round_trip():
    r = np.array([0.1, -0.2, 0.3])
    np.testing.assert_allclose(ctl.matrix_to_rotvec(ctl.rotvec_to_matrix(r)), r, atol=1e-12)
    x_d = (np.zeros(3), ctl.rot_z(0.2))
    x = (np.array([0.0, 0.0, 0.01]), np.eye(3))
    np.testing.assert_allclose(ctl.pose_error(x_d, x), [0, 0, -0.01, 0, 0, 0.2], atol=1e-12)


def test_trajectory_ends_and_holds_at_goal():
    x_i = (np.array([0.0, 0.0, 0.05]), np.eye(3))
    x_g = (np.zeros(3), ctl.rot_z(0.1))
    p, R = ctl.linear_trajectory(x_i, x_g, 5.0, 10.0)
    np.testing.assert_allclose(p, [0, 0, 0.025])
    np.testing.assert_allclose(ctl.matrix_to_rotvec(R), [0, 0, 0.05], atol=1e-12)
    p, R = ctl.linear_trajectory(x_i, x_g, 12.0, 10.0)
    np.testing.assert_allclose(p, 0)


def test_joint_velocities_invert_jacobian():
    rng = np.random.default_rng(0)
    jac = rng.normal(size=(6, 6))
    v = rng.normal(size=6)
    np.testing.assert_allclose(jac @ ctl.joint_velocities(jac, v, damping=1e-6), v, atol=1e-6)
