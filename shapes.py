"""shapes.py: the boxes that scene.py builds its exact holes, chamfers and gears from, and the rotations they
need; numpy only (with control.py's rot_z). Each builder returns [(half extents (3,), centre (3,), rotation
(3, 3))] in the part's own frame, metres.
"""
import numpy as np

import tacrl_flat  # noqa: F401  (first: where another package shadows one of our modules, one line says so)
from control import rot_z


def quat_from_matrix(R):
    """Rotation matrix (3, 3) -> pybullet quaternion (x, y, z, w)."""
    w = np.sqrt(max(1e-12, 1.0 + R[0, 0] + R[1, 1] + R[2, 2])) / 2.0
    if w > 1e-3:
        return [(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w), w]
    i = int(np.argmax(np.diag(R)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = np.sqrt(max(1e-12, 1.0 + R[i, i] - R[j, j] - R[k, k])) * 2.0
    q = [0.0, 0.0, 0.0, (R[k, j] - R[j, k]) / s]
    q[i], q[j], q[k] = s / 4.0, (R[j, i] + R[i, j]) / s, (R[k, i] + R[i, k]) / s
    return q


def ring_boxes(r_in, thick, z0, z1, n):
    """A regular n-gon hole of inscribed radius r_in between heights z0 < z1, walled by n boxes of
    radial thickness `thick`. Returns [(half_extents, position, R)]. The walls are a little longer
    than a side so that their corners close; the overlap lies outside the hole."""
    side = 2.0 * (r_in + thick) * np.tan(np.pi / n)
    out = []
    for i in range(n):
        a = 2.0 * np.pi * i / n
        pos = ((r_in + thick / 2) * np.cos(a), (r_in + thick / 2) * np.sin(a), (z0 + z1) / 2)
        out.append(((thick / 2, side / 2, (z1 - z0) / 2), pos, rot_z(a)))
    return out


def chamfer_boxes(r_in, c, n, thick=0.002):
    """A c x 45 deg chamfer at z in [-c, 0] on an n-gon of inscribed radius r_in: one box per side
    whose inner face is the slope from (r_in, -c) to (r_in + c, 0); the box lies outward and below
    the slope, inside the wall and the top ring, so nothing sticks into the hole or above the top."""
    side = 2.0 * (r_in + c + thick) * np.tan(np.pi / n)
    slope = c * np.sqrt(2.0)
    out = []
    for i in range(n):
        a = 2.0 * np.pi * i / n
        # in the wall's own frame (x radial out, z up): slope mid-point, then half the thickness
        # along the outward-down normal (1, 0, -1)/sqrt(2)
        mid = np.array([r_in + c / 2, 0.0, -c / 2]) + thick / 2 * np.array([1.0, 0.0, -1.0]) / np.sqrt(2)
        R = rot_z(a) @ np.array([[np.cos(np.pi / 4), 0, np.sin(np.pi / 4)], [0, 1, 0],
                                     [-np.sin(np.pi / 4), 0, np.cos(np.pi / 4)]])
        # box axes: x = slope normal (outward-down), y = tangent, z = along the slope
        out.append(((thick / 2, side / 2, slope / 2), tuple(rot_z(a) @ mid), R))
    return out


def plate_boxes(opening, size, z0, z1):
    """A square plate of side `size` with a square opening of half-side `opening`, as four boxes."""
    h, w = (z1 - z0) / 2, (size / 2 - opening) / 2
    zc = (z0 + z1) / 2
    return [((w, size / 2, h), (opening + w, 0.0, zc), np.eye(3)),
            ((w, size / 2, h), (-opening - w, 0.0, zc), np.eye(3)),
            ((opening, w, h), (0.0, opening + w, zc), np.eye(3)),
            ((opening, w, h), (0.0, -opening - w, zc), np.eye(3))]


def gear_teeth(r_root, r_tip, width, n, z0, z1, phase=0.0):
    """n radial teeth, boxes from r_root to r_tip, at angles phase + 2 pi i / n."""
    out = []
    for i in range(n):
        a = phase + 2.0 * np.pi * i / n
        r = (r_root + r_tip) / 2
        out.append((((r_tip - r_root) / 2, width / 2, (z1 - z0) / 2), (r * np.cos(a), r * np.sin(a), (z0 + z1) / 2),
                    rot_z(a)))
    return out


def to_world(R, wrench):
    """A tool-frame wrench (6,) in world axes, given the tool's rotation R."""
    return np.concatenate([R @ wrench[:3], R @ wrench[3:]])


def board_bumps(r_clear, n, heights, radii, r_max, seed):
    """n bumps on a board's top: [(sphere radius, centre (x, y, z))] in the board frame, each sphere sunk so that a
    cap of a height in heights (lo, hi) and a radius in radii (lo, hi) stands above the top (z = 0), wholly outside
    r_clear of the axis (the hole and its chamfer stay exact) and within r_max of it."""
    rng, out = np.random.default_rng(seed), []
    while len(out) < n:
        h, a = rng.uniform(*heights), rng.uniform(*radii)
        rho = (a * a + h * h) / (2 * h)                           # the sphere whose cap that is
        d = np.sqrt(rng.uniform((r_clear + rho) ** 2, r_max ** 2))   # uniform over the area
        phi = rng.uniform(0, 2 * np.pi)
        out.append((rho, (d * np.cos(phi), d * np.sin(phi), h - rho)))
    return out
