"""sim.py: the paper's assembly task as an env, in the PyBullet workcell of scene.py (paper Sec. 4.1-4.3.2,
5.1.1). What this file implements of the paper:
    Eq. 6      the hybrid policy's hand-designed part, tau(t) and K -> AssemblyEnv.reset (control.py)
    Eq. 11     task-attention ROI                              -> roi_box
    Eq. 12     action -> F_d                                   -> AssemblyEnv.action_to_fd
    Eq. 13-15  error injection                                 -> AssemblyEnv.reset
    Eq. 17-18  reward and success                              -> reward, is_success, AssemblyEnv.step

`AssemblyEnv` follows Gymnasium's API: reset(seed, options) -> (obs, info) and step(action) -> (obs,
reward, terminated, truncated, info). With gymnasium installed (`pip install -e ".[gym]"`) it is a
gymnasium.Env with spaces and render(), and importing sim registers `tacrl/PegInsertion-v0` and
`tacrl/GearInsertion-v0`; without it, the same class works on its own. The policy runs at 5 Hz, the
admittance controller of control.py at 120 Hz, physics at 240 Hz.

Observed poses are relative to the estimated goal X^_g (the task 'origin'), wrenches are in the tool
frame, actions (F_d) in the estimated task frame, and the errors lie along the board's axes: moving or
turning the board on the table changes nothing the policy sees or does. No ground truth (X_g, X_i)
reaches the observation: only the reward and the success check use it. Units: m, rad, N.

Watch the hand-designed policy alone: `python tacrl.py --task peg --eval initial --error-mm 0 --gui`.
"""
import cv2
import numpy as np

import tacrl_flat  # noqa: F401  (first: where another package shadows one of our modules, one line says so)
import control as ctl
from contexts import FAMILIES, FAMILY_TEST_SEED0, context_of, drawn_family, family_context
from scene import (APPROACH, CAM_FULL, CLEAR, CONTROL_HZ, CONTROL_PER_POLICY, FT_RANGE, IMG, POLICY_HZ, R_DOWN,
                   World, full_projection, project, task_features, to_world)

try:                   # optional: the env is a gymnasium.Env where gymnasium is installed
    import gymnasium
    from gymnasium import spaces
except ImportError:
    gymnasium = None

# ---------------------------------------------------------------- the task's numbers (paper Sec. 5.1.1)
MAX_STEPS = 120                                     # policy steps per episode (24 s)
HIST = 32                                           # length of the pose and wrench histories
F_MAX = 10.0                                        # F^max, N
TAU_MAX = 1.0                                       # torque analogue of F^max, N m (our choice)
F_MAX6 = np.array([F_MAX] * 3 + [TAU_MAX] * 3)
# The observed pose relative to X^_g lies within these (m, rad): the tip cannot get 2 m from the
# board (the UR5 reaches 0.85 m from its shoulder) and a rotation vector's parts lie within +-pi.
POSE_BOUND = np.array([2.0] * 3 + [np.pi] * 3, np.float32)
W_REWARD = (1.0, 0.8, 1.0)                          # w1, w2, w3 of Eq. 17
R_SUCC = 100.0                                      # r_succ of Eq. 18
E_TH = 0.002                                        # E_th of Eq. 18, m: tip within 2 mm of X_g
E_R_FINAL = 0.020                                   # final error range, m (x, y, z)
E_ROT_FINAL = 0.1                                   # error about z at the final range, rad
EX_MIN = 0.002                                      # floor of the exploration range, m (K stays finite)
EX_ROT = (0.002, 0.002)                             # exploration about x, y, rad: stiff, so a residual torque
                                                    # cannot tilt the peg enough to jam it (0.05 mm over 25 mm);
                                                    # an env's `tilt` adds the board tilt it must meet
TRAJ_TIME = 10.0                                    # tau(t) from X^_i to X^_g takes this long, s
MASS = np.array([20.0, 20.0, 20.0, 0.4, 0.4, 0.4])  # M of Eq. 5: kg and kg m^2 (see README)
ZETA = 1.0                                          # damping ratio, B = 2 zeta sqrt(K M)
# The vanilla baseline's damping (no K, no estimated poses): the guided controller's B at the final range with
# X^_i over X^_g (W = E_R_FINAL, EX_ROT, E_ROT_FINAL): a full F_d of 5 N moves the tool 35 mm/s, as the guided
# one at 20 mm. Ours, one constant for every episode.
B_FREE = ctl.critical_damping(ctl.stiffness(F_MAX6, np.array([E_R_FINAL] * 3 + list(EX_ROT) + [E_ROT_FINAL])),
                              MASS, ZETA)
# Fig. 11's windows, (height, width) in px of the paper's 800 x 800 view. Its ROI-300 is the view "with suitable task
# attention" (Fig. 8b), every feature within the largest error; ROI-200 "covers more features but not all in maximum
# error"; ROI-100*160 "does not cover the main task features" (Sec. 5.1.4). Our camera (scene.CAM_FOV) sees the task at
# another size, so all but the full view are scaled by the side of Eq. 11's box at E_R_FINAL over PAPER_TASK_SIDE
# (peg 213 px, gear 250 px here): each then covers what the paper's covers (tests/test_sim.py checks it).
ROI_PRESETS = {"full": (800, 800), "300": (300, 300), "200": (200, 200), "100x160": (100, 160)}
PAPER_TASK_SIDE = 300


def exploration_range(e_r, ex_r=None):
    """The Ex_r (m) the env runs with: ex_r, or E_r where none is given, floored at EX_MIN."""
    return max(float(e_r if ex_r is None else ex_r), EX_MIN)


# The world's version, written into each run's eval.json: bumped whenever what a policy sees or meets changes
# (22: the workcell and the 90 deg camera), so that a policy is evaluated only in the world it trained in.
WORLD = 22
WORLD_WHAT = ("a workcell (fence, tape, spare parts), a 90 deg eye-in-hand camera with shot noise, the wrist sensor's "
              "noise and drift, 24 bumps on the board, 0.1 mm clearance at every yaw, observation, action and errors "
              "in the board's frame")


# ---------------------------------------------------------------- Eq. 17-18: reward
def reward(x, x_g, w, f, success):
    """Eq. 17: r = -w1 ||(X - X_g)/W|| - w2 ||F/F_max|| + w3 r_succ.
    x, x_g: poses (p, R); w: workspace W (6,); f: wrench (6,), only its force part counts.
    We use the x, y, z and rotation-about-z parts of X - X_g (the ones the errors live in)."""
    e = ctl.pose_error(x, x_g)[[0, 1, 2, 5]] / w[[0, 1, 2, 5]]
    r_succ = R_SUCC if success else 0.0                               # Eq. 18
    return -W_REWARD[0] * np.linalg.norm(e) - W_REWARD[1] * np.linalg.norm(f[:3] / F_MAX) + W_REWARD[2] * r_succ


def is_success(x, x_g):
    """Eq. 18: ||X - X_g|| < E_th on the tip position. X_g is the fully inserted pose (the peg tip on
    the hole bottom, the gear down on the shaft's shoulder), so this needs 23 mm of insertion into the
    0.1 mm hole (13 mm for the gear): a peg stuck on the surface is >= 23 mm away and cannot pass."""
    return bool(np.linalg.norm(x[0] - x_g[0]) < E_TH)



# ---------------------------------------------------------------- Eq. 11: task-attention ROI
def roi_box(world, x_i, board_pose, e_r, e_rot, directions, margin=8):
    """Eq. 11: ROI = [min(x_min^i, y_min^i), max(x_max^i, y_max^i)] over the alignment directions i.

    The camera rides on the tool, so an error e of the pre-assembly point moves the camera by e. For
    each direction (x, y, z or rotation about z) and each sign we place the camera at X_i + e, project
    the task features into the full view and take the box around everything (plus `margin` px).
    Returns (u0, v0, u1, v1) in pixels of the full 800 x 800 view."""
    cam_rel = world.cam_rel                          # the camera's pose relative to the tip
    p_b, R_b = board_pose
    pts = p_b + task_features(world.task) @ R_b.T
    proj, uv = full_projection(), []
    for d in [None] + list(directions):
        for sign in (-1.0, 1.0):
            p_t, R_t = x_i[0].copy(), x_i[1]
            if d in (0, 1, 2):
                p_t += sign * e_r * R_b[:, d]          # Eq. 13's errors lie along the board's axes
            elif d == 5:
                R_t = ctl.rot_z(sign * e_rot) @ R_t
            cam = (p_t + R_t @ cam_rel[0], R_t @ cam_rel[1])
            uv.append(project(pts, world.camera_matrices(cam), proj))
    uv = np.vstack(uv)
    lo, hi = np.clip(uv.min(0) - margin, 0, CAM_FULL), np.clip(uv.max(0) + margin, 0, CAM_FULL)
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def randomize_problem(randomize, context):
    """What is wrong with training scenes drawn from the families `randomize` in `context` ('' if nothing)."""
    if set(randomize) - set(FAMILIES) or (randomize and context != "train"):
        return f"families among {', '.join(FAMILIES)}, in the training context"
    return ""


def preset_roi(name, centre, scale=1.0):
    """The ablation's fixed windows (height x width in px of the full view, times `scale`) around `centre` (u, v)."""
    hgt, wid = (min(CAM_FULL, round(n * scale)) for n in ROI_PRESETS[name])
    u0 = float(np.clip(centre[0] - wid / 2, 0, CAM_FULL - wid))
    v0 = float(np.clip(centre[1] - hgt / 2, 0, CAM_FULL - hgt))
    return u0, v0, u0 + wid, v0 + hgt


# ---------------------------------------------------------------- the env
def check_action(action, n=6):
    """`action` as a float array of shape (n,): ValueError, naming it, if it is not n finite numbers."""
    try:
        a = np.asarray(action, dtype=float)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != (n,) or not np.all(np.isfinite(a)):
        shown = " ".join(repr(action).split())              # on one line, and short
        shown = shown if len(shown) <= 80 else shown[:77] + "..."
        raise ValueError(f"action {shown}: an action is {n} finite numbers in [-1, 1]"
                         + (f", not an array of shape {a.shape}" if a is not None and a.shape != (n,) else ""))
    return a


def hole_blob(img, dark=20):
    """The hole in the peg board's ROI image: the largest blob darker than `dark` (the hole is black,
    the board dark gray). -> (u, v, r) in pixels (centroid and the radius of a disc of equal area),
    or None when no hole is in view. The two-step baseline servoes on it; keypoint RL observes it."""
    n, _, stats, cents = cv2.connectedComponentsWithStats((img < dark).astype(np.uint8))
    if n < 2:
        return None
    i = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return cents[i][0], cents[i][1], np.sqrt(stats[i, cv2.CC_STAT_AREA] / np.pi)


def hole_keypoint(img):
    """Keypoint RL's vision (Table 1's fourth baseline): the hole as a keypoint found by a classical detector
    (hole_blob), (4,) float32 [u, v, r, found]: the centroid in [-0.5, 0.5] of the image's width, the radius
    over it, and 1; zeros when no hole is in view. It models a keypoint detector that finds the hole's
    centre wherever it is in view and nothing else of the scene (the peg board's hole; the gear's shaft
    is not dark and is never found)."""
    b = hole_blob(img)
    if b is None:
        return np.zeros(4, np.float32)
    u, v, r = b
    return np.array([u / img.shape[1] - 0.5, v / img.shape[0] - 0.5, r / img.shape[1], 1.0], np.float32)


class AssemblyEnv(gymnasium.Env if gymnasium else object):
    """Residual-RL assembly env (Algorithm 1's 'interact with environment').

    task: 'peg' or 'gear'; context: a name in contexts.CONTEXTS, FAMILY:SEED (one scene of a family,
    contexts.FAMILIES), FAMILY:test (a held-out scene of the family drawn each episode), FAMILY:train (one of
    training's side each episode) or a scene.Context itself;
    randomize: families
    whose training scenes (seeds below contexts.FAMILY_TEST_SEED0) each episode draws from, in place of the
    context; e_r: guidance error range E_r (m, x y z; the rotation error about z scales with it, E_ROT_FINAL at
    E_R_FINAL); ex_r: exploration range
    Ex_r (m), sets K through Eq. 8-9, floored at EX_MIN; roi: 'task' (Eq. 11) or a preset name;
    clearance: diametral clearance, m; e_r_max: the largest E_r this env will be set to (at least
    E_R_FINAL and e_r): Eq. 11's ROI covers it, and X_i is raised where needed so that its z error
    still starts the tool CLEAR of the parts (from 20 mm up: at 30 mm X_i is 40 mm above them);
    base_policy: False removes the hand-designed part (the vanilla baseline, Sec. 5.1.2: "without a base
    policy"): no trajectory, no spring toward X^_i or X^_g and no stiffness from the estimated poses;
    the residual's F_d alone drives a free admittance (K = 0, the fixed damping B_FREE); what stays is
    the start at X^_i, the observations, the reward and the curriculum's errors; tilt: the board tilt (rad) that
    Eq. 8's range about x and y covers besides EX_ROT (ours: 0, a level board); render_mode: None or
    'rgb_array' (render() is the external camera's view); ft_noise, image_noise: the wrist sensor's noise and
    drift, the camera's shot noise (FT_NOISE, FT_DRIFT, E_PER_DN), on as on a real robot, off for exact tests.

    obs = {'image': (1, 80, 80) uint8, one channel first (the layout image libraries take for an image), 'pose_hist':
    (32, 6) float32 [x y z (m) rx ry rz (rad)] of the tip relative to X^_g in X^_g's frame, newest last,
    'wrench_hist': (32, 6) float32 [F (N), T (N m)] in the tool frame at the tip, newest last}, and with
    keypoint=True 'keypoint': (4,) float32, the hole found in the image (hole_keypoint; keypoint RL's vision).
    action (6,) in [-1, 1] -> F_d = action * F_max/2 per axis: +-5 N, +-0.5 N m.
    """
    metadata = {"render_modes": ["rgb_array"], "render_fps": POLICY_HZ}

    def __init__(self, task="peg", context="train", e_r=0.0, ex_r=None, roi="task", clearance=1e-4,
                 gui=False, image=True, base_policy=True, e_r_max=None, render_mode=None, ft_noise=True,
                 image_noise=True, keypoint=False, randomize=(), tilt=0.0):
        if task not in ("peg", "gear"):
            raise ValueError(f"unknown task {task!r} (peg, gear)")
        ctx = context_of(context, task)                       # ValueError for a name that is none
        problem = randomize_problem(randomize, context)
        if problem:
            raise ValueError(f"randomize {tuple(randomize)!r}: {problem}")
        if roi != "task" and roi not in ROI_PRESETS:
            raise ValueError(f"unknown roi {roi!r} (task, {', '.join(ROI_PRESETS)})")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"unknown render_mode {render_mode!r} (None, 'rgb_array')")
        self.task, self.context, self.roi_name, self.image_on, self.keypoint = task, context, roi, image, keypoint
        self.base_policy, self.render_mode, self.randomize = base_policy, render_mode, tuple(randomize)
        self.tilt = float(tilt)
        if gymnasium is not None:
            hist = lambda b: spaces.Box(np.tile(-b, (HIST, 1)), np.tile(b, (HIST, 1)), dtype=np.float32)  # noqa: E731
            keypoint_box = spaces.Box(np.float32([-0.5, -0.5, 0, 0]), np.float32([0.5, 0.5, 1, 1]), dtype=np.float32)
            self.observation_space = spaces.Dict({
                "image": spaces.Box(0, 255, (1, IMG, IMG), np.uint8), "pose_hist": hist(POSE_BOUND),
                "wrench_hist": hist(FT_RANGE), **({"keypoint": keypoint_box} if keypoint else {})})
            self.action_space = spaces.Box(-1.0, 1.0, (6,), np.float32)
        self.world = World(task, clearance, gui, ft_noise, image_noise, ctx)
        self.e_r_max = max(E_R_FINAL, e_r, e_r_max or 0.0)
        self.approach = max(APPROACH, round(self.e_r_max + CLEAR, 6))
        # (what builds the same env elsewhere, without a window: evaluate.Worker)
        self.init_kwargs = dict(task=task, context=context, roi=roi, clearance=clearance, image=image,
                                base_policy=base_policy, e_r_max=self.e_r_max, ft_noise=ft_noise,
                                image_noise=image_noise, keypoint=keypoint, randomize=tuple(randomize), tilt=tilt)
        self.set_ranges(e_r, ex_r)
        self.np_random = np.random.default_rng()      # the errors' generator (gymnasium's name for it)
        self.scene_rng = np.random.default_rng(0)     # the scenes' of a family or randomization (not the errors')
        self.roi = None
        self.t, self.steps = 0.0, 0
        self.on_tick = None           # called after each controller tick where set (evaluate's video: its frames)

    def set_ranges(self, e_r, ex_r=None):
        """E_r (guidance error) and Ex_r (exploration) in m; the curriculum calls this between episodes."""
        if e_r > self.e_r_max + 1e-9:
            raise ValueError(f"E_r {e_r * 1000:g} mm is above this env's e_r_max, {self.e_r_max * 1000:g} mm")
        self.e_r = float(e_r)
        self.ex_r = exploration_range(e_r, ex_r)

    @property
    def dt(self):
        return 1.0 / POLICY_HZ

    def _alignment_directions(self):
        return (0, 1) if self.task == "peg" else (0, 1, 5)

    def _compute_roi(self, x_i, x_g):
        """Eq. 11 at the largest error range, or a preset window centred on the task features; the board's
        pose is the one placed (X_g's), so that a board moved or turned on the table keeps its window."""
        w = self.world
        R_b = x_g[1] @ R_DOWN
        board = (x_g[0] - R_b @ w.goal_in_board(), R_b)
        dirs = self._alignment_directions()
        box = lambda e_r: roi_box(w, x_i, board, e_r, E_ROT_FINAL * (e_r / E_R_FINAL), dirs)  # noqa: E731
        if self.roi_name == "task":
            return box(self.e_r_max)
        if self.roi_name == "full":
            return preset_roi("full", (CAM_FULL / 2, CAM_FULL / 2))
        task = box(E_R_FINAL)                   # Fig. 11's windows at our camera's scale (ROI_PRESETS)
        c = roi_box(w, x_i, board, 0.0, 0.0, ())
        return preset_roi(self.roi_name, ((c[0] + c[2]) / 2, (c[1] + c[3]) / 2),
                          max(task[2] - task[0], task[3] - task[1]) / PAPER_TASK_SIDE)

    def reset(self, seed=None, options=None):
        """Eq. 13-15: e ~ U(-1, 1) * E_r in x, y, z and rotation about z, in the board's frame (so that a
        board moved or turned on the table meets the same errors); X^_i = X_i + e, X^_g = X_g + e.
        options: 'error' (4,) fixes e; 'goal_shift' (4,) moves the board (and so X_g) by (dx, dy, dz, dyaw)."""
        if seed is not None:      # as gymnasium.Env.reset(seed) does: the same stream as default_rng(seed)
            self.np_random = np.random.default_rng(seed)
            self.scene_rng = np.random.default_rng([seed, 1])
        options = options or {}
        w, ctx = self.world, self._episode_context()
        w.rebuild(ctx)                 # every episode in a fresh world: it depends on its seed only
        self.scene = ctx               # (this episode's scene, a scene.Context)
        scale = np.array([self.e_r] * 3 + [E_ROT_FINAL * self.e_r / E_R_FINAL])
        e = np.asarray(options["error"], float) if "error" in options else \
            self.np_random.uniform(-1, 1, 4) * scale                                                    # Eq. 13
        w.noise_rng = np.random.default_rng(self.np_random.integers(2 ** 63))     # this episode's sensor noise
        self.x_g, self.x_i = w.place(ctx, np.asarray(options.get("goal_shift", np.zeros(4)), float), self.approach)
        R_e, e_w = ctl.rot_z(e[3]), self.x_g[1] @ R_DOWN @ e[:3]     # e's offset in world axes
        self.x_g_hat = (self.x_g[0] + e_w, R_e @ self.x_g[1])        # Eq. 15
        self.x_i_hat = (self.x_i[0] + e_w, R_e @ self.x_i[1])        # Eq. 14
        self.error = e
        ex_rot = max(E_ROT_FINAL * self.ex_r / E_R_FINAL, 0.01)
        ex = np.array([self.ex_r] * 3 + [r + self.tilt for r in EX_ROT] + [ex_rot])     # Eq. 8's E_r
        # Eq. 6's hand-designed part: tau(t) from X^_i to X^_g and K from Eq. 8-9 (none for the vanilla
        # baseline: a free admittance); step() adds the residual's F_d
        self.controller = ctl.HybridPolicy(self.x_i_hat, self.x_g_hat, ex, F_MAX6, MASS, TRAJ_TIME, ZETA,
                                           1.0 / CONTROL_HZ, b_free=None if self.base_policy else B_FREE)
        w.move_to(self.x_i_hat)
        w.command(np.zeros(6))
        w.step_physics(4)
        w.move_to(self.x_i_hat)
        w.tare()
        if self.roi is None or self._roi_key != (ctx, self.roi_name):
            self.roi, self._roi_key = self._compute_roi(self.x_i, self.x_g), (ctx, self.roi_name)
        self.t, self.steps = 0.0, 0
        self.f_tool, self.f_tick = np.zeros(6), np.zeros(6)
        x = w.tool_pose()
        self.pose_hist = np.repeat(self._rel_pose(x)[None], HIST, 0)
        self.wrench_hist = np.zeros((HIST, 6), np.float32)
        return self._obs(), self._info(x, False)

    def _episode_context(self):
        """This episode's scene: the context's, a held-out scene of its family (FAMILY:test) or one of training's
        side (FAMILY:train), or a training scene of the randomized families."""
        drawn = drawn_family(self.context)
        if drawn:
            return family_context(drawn[0], drawn[1] + int(self.scene_rng.integers(FAMILY_TEST_SEED0)), self.task)
        if self.randomize:
            family = self.randomize[self.scene_rng.integers(len(self.randomize))]
            return family_context(family, int(self.scene_rng.integers(FAMILY_TEST_SEED0)), self.task)
        return context_of(self.context, self.task)

    def _rel_pose(self, x):
        """Tip pose relative to X^_g, in X^_g's frame: [x y z rx ry rz] (m, rad), float32."""
        p_g, R_g = self.x_g_hat
        return np.concatenate([R_g.T @ (x[0] - p_g), ctl.matrix_to_rotvec(R_g.T @ x[1])]).astype(np.float32)

    def _obs(self):
        img = self.world.render_roi(self.roi) if self.image_on else np.zeros((IMG, IMG), np.uint8)
        obs = {"image": img[None], "pose_hist": self.pose_hist.copy(), "wrench_hist": self.wrench_hist.copy()}
        return {**obs, "keypoint": hole_keypoint(img)} if self.keypoint else obs

    def _info(self, x, success):
        depth = float(self.x_i[0][2] - self.approach - x[0][2])   # tip below the part's top (hole or shaft), m
        # X - X_g (x, y, z in m, rotation about z in rad): what Eq. 17 measures, known in training only
        offset = ctl.pose_error(x, self.x_g)[[0, 1, 2, 5]]
        return {"success": success, "depth": depth, "t": self.t, "f_tool": self.f_tool.copy(), "goal_offset": offset,
                "f_world": to_world(x[1], self.f_tool),
                "e_r": self.e_r, "ex_r": self.ex_r, "error": self.error.copy(), "roi": self.roi}

    def task_rotation(self):
        """The estimated task frame's orientation in world: the board as the robot believes it lies (X^_g's
        yaw), z up. Observed poses are relative to X^_g and wrenches are in the tool frame, so they turn
        with the board; actions are given in this frame, so that they turn with it too."""
        return self.x_g_hat[1] @ R_DOWN                 # X^_g = rot_z(yaw^) R_DOWN, and R_DOWN R_DOWN = I

    def action_to_fd(self, action):
        """a in [-1, 1]^6 -> F_d (6,) = a * F_max/2, +-5 N and +-0.5 N m in the estimated task frame (Eq. 12),
        returned in world axes at the tip. Values beyond +-1 are clipped; an action that is not 6 finite
        numbers is a ValueError (a NaN would reach the physics and corrupt the rest of the episode)."""
        f = np.clip(check_action(action), -1.0, 1.0) * F_MAX6 / 2
        R = self.task_rotation()
        return np.concatenate([R @ f[:3], R @ f[3:]])

    def step(self, action):
        w = self.world
        f_d = self.action_to_fd(action)
        f_sum = np.zeros(6)
        for _ in range(CONTROL_PER_POLICY):            # the 120 Hz controller, Eq. 5-6
            self.f_tick = w.tick(self.controller, self.t, self.f_tick, f_d)
            f_sum += self.f_tick
            self.t += 1.0 / CONTROL_HZ
            if self.on_tick is not None:
                self.on_tick()
        # The wrench the policy sees is the mean over the 0.2 s step: rigid contact makes the
        # per-tick reading chatter (impacts of 10-20 N between empty ticks) around the right mean.
        self.f_tool = f_sum / CONTROL_PER_POLICY
        self.steps += 1
        x = w.tool_pose()
        success = is_success(x, self.x_g)
        r = reward(x, self.x_g, self.controller.w, to_world(x[1], self.f_tool), success)
        self.pose_hist = np.vstack([self.pose_hist[1:], self._rel_pose(x)[None]])
        self.wrench_hist = np.vstack([self.wrench_hist[1:], self.f_tool.astype(np.float32)[None]])
        truncated = not success and self.steps >= MAX_STEPS
        return self._obs(), float(r), success, truncated, self._info(x, success)

    def __enter__(self):          # `with AssemblyEnv(...) as env:` closes it (gymnasium.Env does the same)
        return self

    def __exit__(self, *exc):
        self.close()

    def render(self):
        """The external camera's RGB view (scene.VIDEO_H, VIDEO_W, 3) uint8, for render_mode 'rgb_array'; else None."""
        return self.world.render_external() if self.render_mode == "rgb_array" else None

    def close(self):
        if self.world is not None:           # closing twice is allowed (gymnasium's contract)
            self.world.close()
            self.world = None


if gymnasium is not None:     # gymnasium.make("tacrl/PegInsertion-v0"): the paper's task, errors up to 20 mm
    for _name, _task in (("PegInsertion-v0", "peg"), ("GearInsertion-v0", "gear")):
        gymnasium.register(f"tacrl/{_name}", entry_point=AssemblyEnv, max_episode_steps=MAX_STEPS,
                           kwargs={"task": _task, "e_r": E_R_FINAL})


def run_episode(env, act, seed=None, options=None, on_step=None):
    """Reset env, then step act(obs) -> action until the episode ends (success or time-out). A policy
    with memory (an act with a reset method) is reset after the env. on_step(obs, r, info) sees every
    step. Returns (success, the last step's info, the return)."""
    obs, info = env.reset(seed=seed, options=options)
    if hasattr(act, "reset"):
        act.reset()
    ret, done = 0.0, False
    while not done:
        obs, r, term, trunc, info = env.step(act(obs))
        ret += r
        if on_step is not None:
            on_step(obs, r, info)
        done = term or trunc
    return term, info, ret


