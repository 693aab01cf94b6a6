"""baselines.py: the classical two-step baseline of the paper's comparison (Sec. 5.1.2, Table 1):
visual servoing on the eye-in-hand image to the hole, a spiral search with contact-state detection,
then insertion. Hand-designed, no learning; it acts through the same hybrid controller (Eq. 6) as the
learned policy, by choosing F_d. The paper does not describe its implementation: this one is ours
(README, difference 11). The other baselines of Table 1 are flags of tacrl.py: `--vanilla` (no
base policy: F_d alone moves the tool) and `--obs v` (vision only).

    python tacrl.py --task peg --eval two-step --error-mm 20 --episodes 20
"""
import numpy as np

import tacrl_flat  # noqa: F401  (first: where another package shadows one of our modules, one line says so)
import sim


def blob_features(b, k):
    """Regression features of a hole blob (u, v, r) seen at servo step k (the tool is lower each step)."""
    u, v, r = (float(x) / sim.IMG for x in b)
    f = np.array([1.0, u, v, r, u * u, v * v, u * v, u * r, v * r])
    return np.concatenate([f, k / 10.0 * f[:4]])


NAMES = ("initial", "two-step")


def make(name, env):
    """A baseline by name, ready to act on `env`: initial (the hand-designed policy alone, F_d = 0) or
    two-step (a TwoStep, calibrated on env: its fit's median error is then `fit_error`, m)."""
    if name == "initial":
        return lambda obs: np.zeros(6)
    if name != "two-step":
        raise ValueError(f"no baseline {name!r}: {', '.join(NAMES)}")
    ts = TwoStep(env)
    ts.fit_error = ts.calibrate()
    return ts


class TwoStep:
    """The classical two-step approach: (1) visual servoing on the eye-in-hand image to the hole,
    (2) a spiral search with contact-state detection, then insertion. No learning; it acts through
    the same hybrid controller (Eq. 6) as our policy, by choosing F_d.

    Calibration (`calibrate`) is what a hand-designed pipeline does once: with known errors (seeds
    apart from evaluation) it runs the servo steps with random lateral forces and fits, by least
    squares, the tool's lateral offset from the hole (x, y) from the hole's blob in the image
    (centroid, radius, their squares and products, and the step: the blob also moves with the
    height, which falls along tau(t), and with the unknown height and yaw errors). Phases, per step:
      servo    (the first SERVO steps) the image gives the tool's offset o from the hole, the tool's
               pose its displacement d from the trajectory, so the error is e = o - d; average it and
               set the lateral F_d = K e, which moves the tool by -e (free space: X = X_d - F_d/K)
      descend  hold that F_d while tau(t) lowers the peg, until the wrist reads CONTACT N upward
      spiral   add an Archimedean spiral (PITCH between turns, STEP of arc a step; commanded
               SPIRAL_GAIN times larger, so the force beats the friction of the pressed peg) to the lateral
               target and press PRESS x 5 N, until the tip drops DROP below where contact began
      insert   set the lateral F_d to hold the tool where it is (no spring force pressing the peg
               against the wall of the 0.1 mm hole) and press with the full 5 N
    The constants were set by hand on calibration seeds (seed 500 +), never on evaluation seeds."""
    SERVO = 8
    CONTACT, PRESS, DROP = 0.5, 0.0, 0.0008
    PITCH, STEP, SPIRAL_GAIN = 0.0006, 0.0004, 3.0

    def __init__(self, env):
        self.env, self.coef, self.bias = env, None, np.zeros(2)

    def calibrate(self, episodes=100, seed=500):
        """Fit the image -> lateral offset map; returns its median error on the fitted samples, m."""
        env, feats, offsets = self.env, [], []
        rng = np.random.default_rng(seed)
        scale = np.array([sim.E_R_FINAL] * 3 + [sim.E_ROT_FINAL])     # Eq. 13 at the final range
        for i in range(episodes):       # each episode's sensor noise seeded too: the fit is the same in every process
            obs, info = env.reset(seed=seed * 100003 + i, options={"error": rng.uniform(-1, 1, 4) * scale})
            for k in range(self.SERVO):
                b = sim.hole_blob(obs["image"][0])
                if b is not None:
                    feats.append(blob_features(b, k))
                    offsets.append(info["goal_offset"][:2])           # X - X_g, the truth, x and y
                obs, _, _, _, info = env.step(np.r_[rng.uniform(-0.7, 0.7, 2), np.zeros(4)])
        feats, offsets = np.array(feats), np.array(offsets)
        self.coef = np.linalg.lstsq(feats, offsets, rcond=None)[0]            # (13, 2)
        # second pass: run the servo itself on more calibration errors; its mean offset at the end is
        # a bias of the fit near the hole (where the servo ends), which we then subtract
        self.bias, ends = np.zeros(2), []
        for i in range(episodes, episodes + episodes // 2):
            obs, info = env.reset(seed=seed * 100003 + i, options={"error": rng.uniform(-1, 1, 4) * scale})
            self.reset()
            for k in range(self.SERVO + 4):
                obs, _, _, _, info = env.step(self(obs))
            ends.append(info["goal_offset"][:2])
        self.bias = np.mean(ends, 0)
        return float(np.median(np.abs(feats @ self.coef - offsets)))

    def _displacement(self, obs):
        """The tool's lateral displacement from the trajectory (m, world x and y), from its pose
        relative to X^_g (the estimate, which the robot knows)."""
        return (self.env.x_g_hat[1] @ obs["pose_hist"][-1, :3])[:2]

    def reset(self):
        self.k, self.phase = 0, "servo"
        self.a = np.zeros(6)
        self.z_contact, self.theta = None, 0.0
        self.lateral, self.estimates = np.zeros(2), []

    def __call__(self, obs):
        w = self.env.controller.w[:2]                        # W (x, y): F_d = K d needs a = d / W
        z = float(obs["pose_hist"][-1, 2])               # tip depth along X^_g's z (down), m
        fz = -float(obs["wrench_hist"][-1, 2])           # upward contact force, N (tool z points down)
        if self.phase == "servo":
            b = sim.hole_blob(obs["image"][0])
            if b is not None:
                self.estimates.append(blob_features(b, self.k) @ self.coef - self._displacement(obs))
                self.lateral = np.mean(self.estimates, 0) / w
            self.k += 1
            if self.k >= self.SERVO:
                self.phase = "descend"
        elif self.phase == "descend" and fz > self.CONTACT:
            self.phase, self.z_contact = "spiral", z
        elif self.phase == "spiral":
            if z > self.z_contact + self.DROP:    # in the hole: no lateral spring force from here on
                self.phase = "insert"
                self.lateral = -self._displacement(obs) / w
            else:
                rho = max(self.PITCH * self.theta / (2 * np.pi), self.STEP)
                self.theta += self.STEP / rho
        self.a[:] = 0.0
        spiral = np.zeros(2)
        if self.phase == "spiral":
            rho = self.PITCH * self.theta / (2 * np.pi)
            spiral = rho * np.array([np.cos(self.theta), np.sin(self.theta)])
        if self.phase == "insert":
            self.a[:2] = np.clip(self.lateral, -1, 1)
        else:
            self.a[:2] = np.clip(self.lateral + (self.SPIRAL_GAIN * spiral + self.bias) / w, -1, 1)
        self.a[2] = {"spiral": self.PRESS, "insert": 1.0}.get(self.phase, 0.0)
        a = self.a.copy()                              # planned in world x, y; the env takes the task frame's
        a[:2] = self.env.task_rotation()[:2, :2].T @ a[:2]
        return a
