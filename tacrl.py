"""tacrl.py: command line of tacrl, the companion code of Wang et al., "Task attention-based multimodal
fusion and curriculum residual learning for context generalization in robotic assembly" (2024).

Training (Algorithm 1): the hybrid policy of Sec. 4.1 with the residual TA-MRP (policy.py) learnt
by SAC, the error range growing with the adaptive curriculum of Eq. 16 (curriculum.py):

    python tacrl.py --task peg                         # train, then evaluate at 5/10/15/20 mm
    python tacrl.py --resume runs/peg-ts-ptv-adaptive-s0
    python tacrl.py --task peg --eval runs/peg-ts-ptv-adaptive-s0/policy.pt --error-mm 20 --episodes 20

Evaluation of the hand-designed policy alone (F_d = 0), and of the classical two-step baseline:

    python tacrl.py --task peg --eval initial --error-mm 0 --episodes 20
    python tacrl.py --task gear --eval initial --error-mm 20 --episodes 20 --json gear20.json
    python tacrl.py --task peg --eval initial --context loc-1 --video peg.mp4
    python tacrl.py --task peg --eval two-step --error-mm 20

The experiments (issue 4): baselines `--vanilla` and `--obs v`, ablations `--obs`, `--curriculum`,
`--roi`; `--seeds 0,1,2` trains one run a seed in parallel; `--archive "runs/*"` copies the small
files of finished runs into results/, which the repository keeps; `--report "results/*"` writes
docs/RESULTS.md (Tables 1 and 2, figures) from them.

A run directory holds config.json, ckpt.pt (networks, optimisers, curriculum, RNG states; every
episode), replay/ (one .npz per episode: the replay buffer), metrics.csv, and at the end policy.pt,
curves.png and eval.json.
"""
import argparse
import collections
import csv
import json
import os
import re
import sys
import time
from dataclasses import asdict, dataclass, fields

import numpy as np

import sim


@dataclass
class Args:
    task: str = "peg"            # 'peg' (0.1 mm clearance) or 'gear' (Sec. 5.1.1)
    eval: str = ""               # evaluate instead of training: 'initial' (F_d = 0), 'two-step' or a policy.pt
    error_mm: float = 20.0       # evaluation: E_r (Eq. 13-15); training: the final range of the curriculum
    episodes: int = 20           # evaluation episodes (the paper: 20 test trials)
    context: str = "train"       # board location / background (sim.CONTEXTS)
    roi: str = "task"            # 'task' (Eq. 11) or a preset of the ROI ablation
    clearance_mm: float = 0.1    # diametral clearance, mm
    seed: int = 0                # seeds the errors, the networks and the replay sampling
    json: str = ""               # also write the evaluation row as JSON to this file
    video: str = ""              # record the first evaluation episode from an external camera (.mp4)
    gui: bool = False            # open the PyBullet window
    # training (Algorithm 1)
    train_episodes: int = 300    # episodes of training
    obs: str = "ts-ptv"          # observation variant (policy.OBS_KINDS)
    curriculum: str = "adaptive"  # error curriculum (curriculum.KINDS)
    updates: int = 200           # SAC gradient steps after each episode (the paper: 200)
    warmup: int = 20             # episodes of uniform random actions before the first update (authors' loop: 20)
    target_entropy: float = -6.0  # SAC's entropy target (the usual -|A| = -6)
    prior_weight: float = 0.0    # actor pays this * |mean action|^2 for leaving F_d = 0 (not in the paper; 0: off)
    batch: int = 64              # SAC batch size
    buffer: int = 50000          # replay capacity, transitions
    lr: float = 3e-4             # Adam step size of actor, critics and temperature
    gamma: float = 0.95          # discount (0.99 let the critics thrash: see README)
    aux_weight: float = 0.0      # weight of an auxiliary X - X_g regression (not in the paper; 0: off)
    critic: str = "privileged"   # 'privileged' (critics read X - X_g: README difference 13) or 'multimodal' (the paper)
    vanilla: bool = False        # the 'vanilla' baseline: no trajectory guidance, the residual acts alone
    device: str = "auto"         # auto, cpu or cuda
    threads: int = 0             # torch CPU threads (0: torch's default, one per core)
    eval_levels: str = "5,10,15,20"  # error ranges (mm) of the evaluation after training (Table 2)
    run_dir: str = ""            # where the run lives; default runs/<task>-<obs>-<curriculum>[-e<mm>][-roi-<roi>][-<critic>]-s<seed>
    seeds: str = ""              # e.g. 0,1,2: independent training runs in parallel processes, one a seed
    archive: str = ""            # copy the small files of these finished run dirs to results/ (comma-separated globs)
    report: str = ""             # regenerate docs/RESULTS.md from these run dirs (comma-separated globs)
    report_dir: str = "docs"     # where --report writes RESULTS.md and its figures
    resume: str = ""             # continue the run in this directory


HELP = {
    "task": "peg or gear", "eval": "'initial' (the hand-designed policy alone), 'two-step' (the classical "
    "baseline: visual servoing, spiral search, insertion) or a policy.pt to evaluate; "
    "without it, train", "error_mm": "error range E_r in mm (0..30): evaluated, or the curriculum's final range",
    "episodes": "number of evaluation episodes",
    "context": f"one of {', '.join(sim.CONTEXTS)}", "roi": f"task or one of {', '.join(sim.ROI_PRESETS)}",
    "clearance_mm": "diametral clearance of the peg / gear bore, mm", "seed": "random seed",
    "json": "write the evaluation row to this JSON file", "video": "record the first evaluation episode to this .mp4",
    "gui": "open the PyBullet GUI", "train_episodes": "training episodes",
    "obs": "observations: pt, ts-pt, ts-ptv, or v (image only: the visual baseline)", "curriculum": "adaptive, none, g2-c30, g2-c10, g2-c2 or ex10 (E_r adaptive, Ex_r "
    "held at 10 mm: the observation ablation)",
    "updates": "gradient steps after each episode",
    "warmup": "episodes of uniform random actions before the first update",
    "prior_weight": "weight of the actor's penalty on |mean action|^2, which keeps the residual near F_d = 0 "
    "(the hand-designed policy) unless the critics value more (0: the paper's SAC)",
    "target_entropy": "SAC's target entropy of the 6-D action (-6 is the usual -|A|; lower is less noisy)", "threads": "torch CPU threads, 0 = all cores",
    "batch": "SAC batch size", "buffer": "replay capacity (transitions)", "lr": "learning rate",
    "gamma": "discount factor", "vanilla": "train the 'vanilla' baseline: SAC without the base policy's "
    "trajectory (the residual acts alone through the same compliance controller)", "aux_weight": "weight of the auxiliary loss that regresses X - X_g "
    "from the critic's features (0: the paper's plain SAC); needs --critic multimodal",
    "critic": "privileged (an asymmetric actor-critic: the critics read the tip's offset from the true goal, "
    "X - X_g, which Eq. 17's reward already uses, and the time; the actor, the policy that is deployed, keeps "
    "the paper's inputs and gets an encoder of its own) or multimodal (the paper: the critics see what the "
    "actor sees, through the encoder they share)", "device": "auto, cpu or cuda", "run_dir": "run directory",
    "eval_levels": "comma-separated error ranges (mm) evaluated after training",
    "archive": "copy what the report reads of these finished run directories (comma-separated glob patterns, "
    "e.g. 'runs/*': config, metrics, evaluations, policy.pt, curves; not the checkpoint or the replay) to "
    "results/<run name>/, which the repository keeps",
    "report": "regenerate docs/RESULTS.md and its figures from these run directories (comma-separated glob "
    "patterns, e.g. 'results/*'); evaluates what the report needs and has not got yet",
    "report_dir": "where --report writes RESULTS.md and its figures",
    "seeds": "comma-separated seeds: one training run each, in parallel processes up to the number of cores "
    "(run dirs get -s<seed>; each logs to its train.log)",
    "resume": "run directory to continue (its config.json wins over other flags)",
}


class ArgError(Exception):
    pass


BASELINES = ("initial", "two-step")      # --eval names that are not policy files


def parse_args(argv=None):
    class Parser(argparse.ArgumentParser):
        def error(self, message):            # one line, exit code 2, no usage dump
            raise ArgError(message)
    ap = Parser(description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    for f in fields(Args):
        flag = "--" + f.name.replace("_", "-")
        if f.type is bool or f.type == "bool":
            ap.add_argument(flag, action="store_true", help=HELP[f.name])
        else:
            typ = {"int": int, "float": float, "str": str}.get(f.type, f.type) if isinstance(f.type, str) else f.type
            ap.add_argument(flag, type=typ, default=f.default, help=f"{HELP[f.name]} (default: {f.default})")
    a = Args(**vars(ap.parse_args(argv)))
    if a.resume:
        a = load_config(a.resume)
    check_args(a)
    return a


def check_args(a):
    import curriculum
    import policy
    if a.task not in ("peg", "gear"):
        raise ArgError(f"--task must be peg or gear, not {a.task!r}")
    if a.eval and a.eval not in BASELINES and not os.path.isfile(a.eval):
        raise ArgError(f"--eval must be {', '.join(BASELINES)} or an existing policy.pt file, not {a.eval!r}")
    if a.eval == "two-step" and a.task != "peg":
        raise ArgError("--eval two-step is the peg-in-hole baseline (Table 1); it has no gear version")
    if not 0.0 <= a.error_mm <= 30.0:
        raise ArgError(f"--error-mm must be within 0..30, not {a.error_mm}")
    for name in ("episodes", "train_episodes", "batch", "buffer"):
        if getattr(a, name) < 1:
            raise ArgError(f"--{name.replace('_', '-')} must be at least 1, not {getattr(a, name)}")
    for name in ("updates", "warmup", "threads"):
        if getattr(a, name) < 0:
            raise ArgError(f"--{name} must be at least 0, not {getattr(a, name)}")
    if not (0.0 < a.lr < 1.0 and 0.0 < a.gamma < 1.0):
        raise ArgError(f"--lr and --gamma must be within (0, 1), not {a.lr} and {a.gamma}")
    if a.critic not in CRITICS:
        raise ArgError(f"--critic must be one of {', '.join(CRITICS)}, not {a.critic!r}")
    if a.aux_weight > 0 and a.critic != "multimodal":
        raise ArgError("--aux-weight trains the encoder the critics share with the actor: it needs --critic multimodal")
    if a.aux_weight < 0 or a.prior_weight < 0:
        raise ArgError(f"--aux-weight and --prior-weight must be at least 0, not {a.aux_weight} and {a.prior_weight}")
    if a.context not in sim.CONTEXTS:
        raise ArgError(f"--context must be one of {', '.join(sim.CONTEXTS)}, not {a.context!r}")
    if a.roi != "task" and a.roi not in sim.ROI_PRESETS:
        raise ArgError(f"--roi must be task or one of {', '.join(sim.ROI_PRESETS)}, not {a.roi!r}")
    if not 0.0 < a.clearance_mm <= 2.0:
        raise ArgError(f"--clearance-mm must be within (0, 2], not {a.clearance_mm}")
    if a.video and not a.video.endswith(".mp4"):
        raise ArgError(f"--video must name an .mp4 file, not {a.video!r}")
    if a.obs not in policy.OBS_KINDS:
        raise ArgError(f"--obs must be one of {', '.join(policy.OBS_KINDS)}, not {a.obs!r}")
    if a.curriculum not in curriculum.KINDS:
        raise ArgError(f"--curriculum must be one of {', '.join(curriculum.KINDS)}, not {a.curriculum!r}")
    try:
        levels = [float(x) for x in a.eval_levels.split(",")]
    except ValueError:
        levels = []
    if not levels or not all(0.0 <= x <= 30.0 for x in levels):
        raise ArgError(f"--eval-levels must be comma-separated error ranges in 0..30 mm, not {a.eval_levels!r}")
    if a.device not in ("auto", "cpu", "cuda"):
        raise ArgError(f"--device must be auto, cpu or cuda, not {a.device!r}")
    if a.device == "cuda":
        import torch
        if not torch.cuda.is_available():
            raise ArgError("--device cuda: no CUDA device is available here (use auto or cpu)")
    if a.seeds:
        try:
            seeds = [int(x) for x in a.seeds.split(",")]
        except ValueError:
            seeds = []
        if not seeds or len(set(seeds)) != len(seeds) or a.eval or a.resume:
            raise ArgError(f"--seeds must be distinct comma-separated integers, for training only, not {a.seeds!r}")
    if not a.run_dir:
        a.run_dir = default_run_dir(a)


def default_run_dir(a):
    """runs/<task>-[vanilla-]<obs>-<curriculum>[-e<E_r mm>][-roi-<roi>][-<critic>]-s<seed>: the flags of
    the baselines and ablations are in its name, so that no run overwrites another's directory."""
    name = f"{a.task}-{'vanilla-' if a.vanilla else ''}{a.obs}-{a.curriculum}"
    name += (f"-e{a.error_mm:g}" if a.error_mm != Args.error_mm else "") + (f"-roi-{a.roi}" if a.roi != "task" else "")
    name += f"-{a.critic}" if a.critic != Args.critic else ""
    return os.path.join("runs", f"{name}-s{a.seed}")


def read_json(path):
    with open(path) as f:
        return json.load(f)


def read_config(run_dir):
    """A run's config.json as a dict; runs from before --critic existed had the paper's critics."""
    d = read_json(os.path.join(run_dir, "config.json"))
    d.setdefault("critic", "multimodal")
    return d


def load_config(run_dir):
    try:
        a = Args(**read_config(run_dir))
    except FileNotFoundError:
        raise ArgError(f"--resume {run_dir!r}: no config.json there (not a run directory)")
    except (ValueError, TypeError, AttributeError) as e:      # AttributeError: not a JSON object
        raise ArgError(f"--resume {run_dir!r}: config.json is unreadable ({e})")
    a.run_dir, a.resume, a.eval = run_dir, run_dir, ""
    return a


def mean_std(x):
    """[mean, std], or None where there is nothing to average (no successful episode): JSON null."""
    x = np.asarray(x, float)
    return [float(x.mean()), float(x.std())] if len(x) else None


def policy_env(task, act, context="train", roi="task", clearance_mm=0.1, e_r_mm=0.0, gui=False):
    """A new simulator for evaluating `act` (a loaded policy, or a baseline without these attributes):
    the controller at the Ex_r it was trained with, the ROI and X_i of the E_r it was trained for.
    Always a new one: after resetJointState / resetBasePositionAndOrientation, PyBullet still depends
    on what it simulated before (bullet3 issue 2442; measured here too), so an evaluation in the
    simulator a run trained in would differ from `--eval policy.pt` in a fresh process."""
    return sim.AssemblyEnv(task, context, e_r=e_r_mm / 1000, ex_r=getattr(act, "ex_r", None), roi=roi,
                           clearance=clearance_mm / 1000, gui=gui, use_base_policy=not getattr(act, "vanilla", False),
                           e_r_max=getattr(act, "e_r_max", None))


def evaluate(env, act, episodes, seed, video=None, log=print):
    """Roll out `act(obs) -> action` for `episodes` episodes; returns the Table-1/2-style row:
    success rate, completion time of the successful episodes (s), peak |contact force| per world
    axis in each episode (N) and cumulative reward, each as [mean, std]."""
    succ, times, forces, returns = [], [], [], []
    t0 = time.time()
    for ep in range(episodes):
        peak = np.zeros(3)

        def on_step(obs, r, info, first=ep == 0):
            np.maximum(peak, np.abs(info["f_world"][:3]), out=peak)
            if video is not None and first:
                video.write(env.world.render_external()[:, :, ::-1])
        term, info, ret = sim.run_episode(env, act, seed=seed * 100003 + ep, on_step=on_step)
        succ.append(term)
        returns.append(ret)
        forces.append(peak)
        if term:
            times.append(info["t"])
        el = time.time() - t0
        log(f"episode {ep + 1}/{episodes}  success {int(term)}  time {info['t']:5.1f}s  return {ret:7.1f}  "
            f"|F|max x/y/z {peak[0]:5.1f}/{peak[1]:5.1f}/{peak[2]:5.1f} N  "
            f"elapsed {el:5.0f}s  ETA {el / (ep + 1) * (episodes - ep - 1):4.0f}s")
    forces = np.array(forces)
    return {"success_rate": float(np.mean(succ)), "completion_time_s": mean_std(times),
            "contact_force_x_N": mean_std(forces[:, 0]), "contact_force_y_N": mean_std(forces[:, 1]),
            "contact_force_z_N": mean_std(forces[:, 2]), "cumulative_reward": mean_std(returns),
            "episodes": episodes}


def evaluate_levels(env, act, levels, episodes, seed, log=lambda row: None):
    """Table-2 rows: `evaluate` at each error range E_r in `levels` (mm), with Ex_r held where the
    policy's training ended (act.ex_r: the controller stays as trained; None: Ex_r = E_r)."""
    rows = []
    for mm in levels:
        env.set_ranges(mm / 1000, act.ex_r)
        row = evaluate(env, act, episodes, seed, log=lambda *_: None)
        row.update(error_mm=mm, ex_r_mm=round(env.ex_r * 1000, 3))
        rows.append(row)
        log(row)
    return rows


def format_row(name, row):
    ms = lambda k, f="{:.2f}": "-" if row[k] is None else f"{f.format(row[k][0])} +- {f.format(row[k][1])}"
    return (f"{'policy':<22} {'SR':>5}  {'CT (s)':>14}  {'Fx (N)':>14}  {'Fy (N)':>14}  {'Fz (N)':>14}  {'CR':>16}\n"
            f"{name:<22} {row['success_rate']:5.2f}  {ms('completion_time_s'):>14}  {ms('contact_force_x_N'):>14}  "
            f"{ms('contact_force_y_N'):>14}  {ms('contact_force_z_N'):>14}  {ms('cumulative_reward', '{:.1f}'):>16}")


# ---------------------------------------------------------------- the two-step baseline (Sec. 5.1.2)
def hole_blob(img, dark=20):
    """The hole in the peg board's ROI image: the largest blob darker than `dark` (the hole is black,
    the board dark gray). -> (u, v, r) in pixels (centroid and the radius of a disc of equal area),
    or None when no hole is in view."""
    import cv2
    n, _, stats, cents = cv2.connectedComponentsWithStats((img < dark).astype(np.uint8))
    if n < 2:
        return None
    i = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return cents[i][0], cents[i][1], np.sqrt(stats[i, cv2.CC_STAT_AREA] / np.pi)


def blob_features(b, k):
    """Regression features of a hole blob (u, v, r) seen at servo step k (the tool is lower each step)."""
    u, v, r = (float(x) / sim.IMG for x in b)
    f = np.array([1.0, u, v, r, u * u, v * v, u * v, u * r, v * r])
    return np.concatenate([f, k / 10.0 * f[:4]])


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
        for _ in range(episodes):
            obs, info = env.reset(options={"error": rng.uniform(-1, 1, 4) * scale})
            for k in range(self.SERVO):
                b = hole_blob(obs["image"])
                if b is not None:
                    feats.append(blob_features(b, k))
                    offsets.append(info["goal_offset"][:2])           # X - X_g, the truth, x and y
                obs, _, _, _, info = env.step(np.r_[rng.uniform(-0.7, 0.7, 2), np.zeros(4)])
        feats, offsets = np.array(feats), np.array(offsets)
        self.coef = np.linalg.lstsq(feats, offsets, rcond=None)[0]            # (13, 2)
        # second pass: run the servo itself on more calibration errors; its mean offset at the end is
        # a bias of the fit near the hole (where the servo ends), which we then subtract
        self.bias, ends = np.zeros(2), []
        for _ in range(episodes // 2):
            obs, info = env.reset(options={"error": rng.uniform(-1, 1, 4) * scale})
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
        w = self.env.policy.w[:2]                        # W (x, y): F_d = K d needs a = d / W
        z = float(obs["pose_hist"][-1, 2])               # tip depth along X^_g's z (down), m
        fz = -float(obs["wrench_hist"][-1, 2])           # upward contact force, N (tool z points down)
        if self.phase == "servo":
            b = hole_blob(obs["image"])
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
        return self.a.copy()


# ---------------------------------------------------------------- policies and checkpoints
POSE_SCALE = [sim.E_R_FINAL] * 3 + [sim.E_ROT_FINAL] * 3    # the encoder divides the pose history by these
# The aux target: the lateral part of X - X_g (x, y in m, yaw in rad) over these. Lateral and yaw
# only: the height is mostly known from the pose history and would dominate the loss (55 mm to 0
# in every episode, against +-E_r laterally). 5 mm and 0.025 rad units keep the small errors of the
# curriculum's first levels visible in the loss.
AUX_SCALE = np.array([0.005, 0.005, 0.025])
AUX_DIMS = [0, 1, 3]                          # of info['goal_offset'] (x, y, z, yaw)
EVAL_SEED = 1000                                               # eval seeds: EVAL_SEED + --seed, never a training seed
CRITICS = ("multimodal", "privileged")
STATE_DIM = 7                                 # the privileged critic's obs['state'], see critic_state


def critic_state(info):
    """What --critic privileged adds to the critics' input (7,): X - X_g (x, y over 5 mm, z over
    25 mm, yaw over 0.025 rad), x and y again through tanh(. / 1 mm) so that the last millimetre,
    where the chamfer catches or misses, stands out, and the time over the episode's 24 s."""
    off = info["goal_offset"]
    return np.array([off[0] / 0.005, off[1] / 0.005, off[2] / 0.025, off[3] / 0.025, np.tanh(off[0] / 0.001),
                     np.tanh(off[1] / 0.001), info["t"] * sim.POLICY_HZ / sim.MAX_STEPS], np.float32)


def pick_device(name):
    import torch
    return ("cuda" if torch.cuda.is_available() else "cpu") if name == "auto" else name


def make_sac(a, device):
    import policy
    return policy.SAC(a.obs, POSE_SCALE, sim.F_MAX6, lr=a.lr, gamma=a.gamma, device=device,
                      aux_dim=len(AUX_SCALE) if a.aux_weight > 0 else 0, aux_weight=a.aux_weight,
                      target_entropy=a.target_entropy, prior_weight=a.prior_weight,
                      state_dim=STATE_DIM if a.critic == "privileged" else 0)


def save_atomic(obj, path):
    """torch.save to path.tmp, then rename: an interrupt leaves the old file or the new one."""
    import torch
    torch.save(obj, path + ".tmp")
    os.replace(path + ".tmp", path)


def save_policy(path, sac, a, ex_r, e_r_max):
    """What evaluation needs: the encoder, the actor (the critics stay in ckpt.pt), the exploration
    range Ex_r (m) the training ended with (the stiffness of Eq. 9 it learned to push) and the
    env's largest error range e_r_max (m: its ROI and X_i)."""
    d = {"format": "tacrl-policy-1", "task": a.task, "obs": a.obs, "roi": a.roi, "vanilla": a.vanilla,
         "ex_r": float(ex_r), "e_r_max": float(e_r_max), "enc": sac.enc.state_dict(), "actor": sac.actor.state_dict()}
    if sac.actor_enc is not None:
        d["actor_enc"] = sac.actor_enc.state_dict()
    save_atomic(d, path)


def load_policy(path, task, device="cpu"):
    """policy.pt -> act(obs) -> action, deterministic (the Gaussian's mean). A file that is not a
    tacrl policy, or one trained for another task, is a user error (ArgError)."""
    import torch
    import policy
    try:
        d = torch.load(path, map_location=device, weights_only=True)
        if not isinstance(d, dict) or d.get("format") != "tacrl-policy-1":
            raise ValueError("not a tacrl policy file")
        enc = policy.Encoder(d["obs"]).to(device)
        enc.load_state_dict(d.get("actor_enc", d["enc"]))     # the encoder the actor reads
        actor = policy.Actor(enc.out_dim).to(device)
        actor.load_state_dict(d["actor"])
    except Exception as e:          # corrupt, truncated, foreign: one line for the user
        raise ArgError(f"--eval {path!r}: cannot load the policy ({type(e).__name__}: {str(e).splitlines()[0][:120]})")
    if d["task"] != task:
        raise ArgError(f"--eval {path!r}: this policy was trained for --task {d['task']}, not {task}")
    enc.eval()
    actor.eval()
    act = lambda obs: policy.act(enc, actor, obs, deterministic=True, device=device)   # noqa: E731
    act.vanilla = bool(d.get("vanilla", False))    # evaluate it the way it was trained:
    act.ex_r = d.get("ex_r")                       # with its controller (None: older files, Ex_r = E_r)
    act.e_r_max = d.get("e_r_max", sim.E_R_FINAL)  # and its view (Eq. 11's ROI) and X_i
    act.roi = d.get("roi", "task")
    act.enc, act.actor = enc, actor                # for plots that look inside (behaviour_plot)
    return act


# ---------------------------------------------------------------- training (Algorithm 1)
METRICS = ["episode", "return", "success", "sr15", "e_r_mm", "ex_r_mm", "delta", "steps", "total_steps",
           "updates", "q_loss", "pi_loss", "alpha", "entropy", "aux_loss", "env_s", "update_s", "elapsed_s"]


def rng_state(rng):
    return json.dumps(rng.bit_generator.state)


def set_rng_state(rng, s):
    rng.bit_generator.state = json.loads(s)


def save_episode(path, ep):
    """One episode as ReplayBuffer.add_episode takes it, as plain arrays (np.load needs no pickle)."""
    np.savez(path + ".tmp.npz", act=ep["act"], rew=ep["rew"], term=ep["term"], aux=ep["aux"],
             **{"obs_" + k: v for k, v in ep["obs"].items()})
    os.replace(path + ".tmp.npz", path)


def load_episode(path):
    with np.load(path, allow_pickle=False) as z:
        return {"obs": {k[4:]: z[k] for k in z.files if k.startswith("obs_")},
                "act": z["act"], "rew": z["rew"], "term": z["term"], "aux": z["aux"]}


def episode_files(run_dir):
    d = os.path.join(run_dir, "replay")
    return sorted((int(f[3:9]), os.path.join(d, f)) for f in os.listdir(d) if f.startswith("ep_") and
                  f.endswith(".npz") and ".tmp" not in f)


def drop_unheld(on_disk, steps, capacity):
    """Delete the oldest replay files while the newer ones still fill the ring buffer. on_disk: a
    deque of (path, transitions), oldest first, holding `steps` transitions; returns what is left."""
    while on_disk and steps - on_disk[0][1] >= capacity:
        old, n = on_disk.popleft()
        os.remove(old)
        steps -= n
    return steps


def trim_episode_files(run_dir, capacity, keep_upto):
    """Delete replay files past the checkpoint (an episode cut short by an interrupt) and the oldest
    ones that the ring buffer no longer holds; returns the rest as (deque of (path, transitions),
    oldest first; their transitions summed)."""
    on_disk, steps = collections.deque(), 0
    for n, f in episode_files(run_dir):
        if n > keep_upto:
            os.remove(f)
            continue
        with np.load(f, allow_pickle=False) as z:
            on_disk.append((f, len(z["act"])))
        steps += on_disk[-1][1]
    return on_disk, drop_unheld(on_disk, steps, capacity)


def fmt_time(s):
    s = int(s)
    return f"{s // 3600}h{s // 60 % 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


def train(a, log=lambda msg: print(msg, flush=True)):
    import torch
    import curriculum
    import policy
    device = pick_device(a.device)
    replay_dir = os.path.join(a.run_dir, "replay")
    ckpt_path = os.path.join(a.run_dir, "ckpt.pt")
    if not a.resume and os.path.exists(ckpt_path):
        raise ArgError(f"{a.run_dir!r} already holds a run: continue it with --resume {a.run_dir} "
                       f"or pick another --run-dir")
    os.makedirs(replay_dir, exist_ok=True)
    if a.threads:
        torch.set_num_threads(a.threads)
    torch.manual_seed(a.seed)
    sac = make_sac(a, device)
    curr = curriculum.Curriculum(a.curriculum, final=a.error_mm / 1000)
    env = sim.AssemblyEnv(a.task, a.context, roi=a.roi, clearance=a.clearance_mm / 1000, gui=a.gui,
                          use_base_policy=not a.vanilla, e_r_max=a.error_mm / 1000)   # floored at 20 mm by the env
    env.rng = np.random.default_rng(a.seed)
    sample_rng = np.random.default_rng(a.seed + 1)
    shapes = {"image": (sim.IMG, sim.IMG), "pose_hist": (sim.HIST, 6), "wrench_hist": (sim.HIST, 6)}
    privileged = a.critic == "privileged"
    if privileged:                   # the critics' extra input rides in the replay as one more obs key
        shapes["state"] = (STATE_DIM,)
    buf = policy.ReplayBuffer(a.buffer, shapes, aux_dim=sac.aux_head.out_features if sac.aux_head else 0)
    start, total_steps, elapsed0 = 0, 0, 0.0
    on_disk, on_disk_steps = collections.deque(), 0    # (replay file, transitions) the buffer holds; their sum
    metrics_path = os.path.join(a.run_dir, "metrics.csv")
    if a.resume and os.path.exists(ckpt_path):
        try:
            ck = torch.load(ckpt_path, map_location=device, weights_only=True)
            sac.load_state_dict(ck["sac"])
            curr.load_state_dict(json.loads(ck["curriculum"]))
            set_rng_state(env.rng, ck["env_rng"])
            set_rng_state(sample_rng, ck["sample_rng"])
            torch.set_rng_state(ck["torch_rng"])
            start, total_steps, elapsed0 = int(ck["episode"]), int(ck["total_steps"]), float(ck["elapsed"])
        except Exception as e:
            raise ArgError(f"--resume {a.run_dir!r}: ckpt.pt is corrupt or does not match this run's "
                           f"config ({type(e).__name__}: {str(e).splitlines()[0][:120]})")
        on_disk, on_disk_steps = trim_episode_files(a.run_dir, a.buffer, start)
        for f, _ in on_disk:
            buf.add_episode(load_episode(f))
        with open(metrics_path) as f:
            rows = [r for r in csv.DictReader(f) if int(r["episode"]) <= start]
        with open(metrics_path, "w", newline="") as f:
            w = csv.DictWriter(f, METRICS)
            w.writeheader()
            w.writerows(rows)
        log(f"resumed {a.run_dir} at episode {start} ({len(buf)} transitions in the replay buffer)")
    else:
        trim_episode_files(a.run_dir, a.buffer, 0)
        with open(os.path.join(a.run_dir, "config.json"), "w") as f:
            json.dump({k: v for k, v in asdict(a).items() if k != "resume"}, f, indent=2)
        with open(metrics_path, "w", newline="") as f:
            csv.DictWriter(f, METRICS).writeheader()
    log(f"training {a.task} ({a.obs}, curriculum {a.curriculum} to {a.error_mm:g} mm) on {device}: "
        f"{a.train_episodes} episodes, {a.updates} updates each after {a.warmup}; run dir {a.run_dir}")
    t_start = time.time() - elapsed0
    try:
        for ep in range(start, a.train_episodes):
            # -- interact with the environment (Algorithm 1, line 9)
            t0 = time.time()
            e_r, ex_r = curr.ranges()
            env.set_ranges(e_r, ex_r)
            obs, info = env.reset()
            traj, aux = {k: [v] for k, v in obs.items()}, [info["goal_offset"][AUX_DIMS] / AUX_SCALE]
            if privileged:
                traj["state"] = [critic_state(info)]
            acts, rews, terms, done, ret = [], [], [], False, 0.0
            while not done:
                # warm-up: uniform actions (Spinning Up's start steps), so that the critics have
                # seen the whole action range before the actor starts to follow their gradient
                act = (torch.rand(6) * 2 - 1).numpy() if ep < a.warmup else sac.act(obs)
                obs, r, term, trunc, info = env.step(act)
                for k, v in obs.items():
                    traj[k].append(v)
                if privileged:
                    traj["state"].append(critic_state(info))
                aux.append(info["goal_offset"][AUX_DIMS] / AUX_SCALE)
                acts.append(act)
                rews.append(r)
                terms.append(term)        # only a real end stops the bootstrap; a time-out does not
                ret += r
                done = term or trunc
            episode = {"obs": {k: np.stack(v) for k, v in traj.items()}, "act": np.array(acts, np.float32),
                       "rew": np.array(rews, np.float32), "term": np.array(terms, np.float32),
                       "aux": np.array(aux, np.float32)}
            path = os.path.join(replay_dir, f"ep_{ep + 1:06d}.npz")
            save_episode(path, episode)
            buf.add_episode(episode)
            total_steps += len(acts)
            on_disk.append((path, len(acts)))
            on_disk_steps += len(acts)
            on_disk_steps = drop_unheld(on_disk, on_disk_steps, a.buffer)   # disk keeps what the buffer holds
            t_env = time.time() - t0
            # -- update the policy with SAC (line 10)
            t0, losses = time.time(), []
            if ep + 1 > a.warmup:
                for _ in range(a.updates):
                    losses.append(sac.update(buf.sample(a.batch, sample_rng)))
            t_upd = time.time() - t0
            # -- generate the curriculum with Eq. 16 (line 11)
            success = bool(terms[-1])
            curr.update(success)
            elapsed = time.time() - t_start
            mean = {k: float(np.mean([l[k] for l in losses])) if losses else float("nan")
                    for k in ("q_loss", "pi_loss", "alpha", "entropy", "aux_loss")}
            row = {"episode": ep + 1, "return": round(ret, 3), "success": int(success), "sr15": round(curr.success_rate, 3),
                   "e_r_mm": round(e_r * 1000, 3), "ex_r_mm": round(env.ex_r * 1000, 3),
                   "delta": round(curr.delta, 4), "steps": len(acts), "total_steps": total_steps, "updates": len(losses),
                   **{k: round(v, 5) for k, v in mean.items()}, "env_s": round(t_env, 2), "update_s": round(t_upd, 2),
                   "elapsed_s": round(elapsed, 1)}
            with open(metrics_path, "a", newline="") as f:
                csv.DictWriter(f, METRICS).writerow(row)
            save_atomic({"episode": ep + 1, "total_steps": total_steps, "elapsed": elapsed, "sac": sac.state_dict(),
                         "curriculum": json.dumps(curr.state_dict()), "env_rng": rng_state(env.rng),
                         "sample_rng": rng_state(sample_rng), "torch_rng": torch.get_rng_state()}, ckpt_path)
            eta = (time.time() - t_start - elapsed0) / (ep + 1 - start) * (a.train_episodes - ep - 1)
            log(f"ep {ep + 1:4d}/{a.train_episodes}  R {ret:7.1f}  succ {int(success)}  sr15 {curr.success_rate:4.2f}  "
                f"E_r {e_r * 1000:4.1f}mm  Ex_r {row['ex_r_mm']:4.1f}mm  delta {curr.delta:5.3f}  steps {len(acts):3d}  "
                f"env {t_env:4.1f}s  upd {t_upd:4.1f}s  elapsed {fmt_time(elapsed)}  ETA {fmt_time(eta)}")
        save_policy(os.path.join(a.run_dir, "policy.pt"), sac, a, ex_r=curr.ranges()[1], e_r_max=env.e_r_max)
        plot_curves(metrics_path, os.path.join(a.run_dir, "curves.png"), f"{a.task}, {a.obs}, {a.curriculum}")
        # -- Table-2-style evaluation with a seed never used in training, in a new simulator
        act = load_policy(os.path.join(a.run_dir, "policy.pt"), a.task, device)
        env.close()
        env = None                   # (closed: the finally below must not close it twice)
        env = policy_env(a.task, act, a.context, a.roi, a.clearance_mm, gui=a.gui)
        result = {"task": a.task, "obs": a.obs, "curriculum": a.curriculum, "context": a.context, "roi": a.roi,
                  "seed": a.seed, "eval_seed": EVAL_SEED + a.seed, "train_episodes": a.train_episodes,
                  "train_minutes": round((time.time() - t_start) / 60, 1), "simulator": "new", "rows": []}
        levels = sorted({float(x) for x in a.eval_levels.split(",")})
        result["rows"] = evaluate_levels(env, act, levels, a.episodes, EVAL_SEED + a.seed,
                                         log=lambda row: log(format_row(f"TA-MRP {a.task} {row['error_mm']:g}mm", row)))
    finally:
        if env is not None:
            env.close()
    with open(os.path.join(a.run_dir, "eval.json"), "w") as f:
        json.dump(result, f, indent=2)
    log(f"wrote {a.run_dir}/policy.pt, metrics.csv, curves.png, eval.json")
    return result


def plot_curves(metrics_path, out, title=""):
    """Fig. 10 / 14 style: cumulative reward, success rate over 15, E_r and Ex_r against episode."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    with open(metrics_path) as f:
        rows = list(csv.DictReader(f))
    col = lambda k: np.array([float(r[k]) for r in rows])  # noqa: E731
    ep = col("episode")
    fig, ax = plt.subplots(1, 4, figsize=(16, 3.4))
    ax[0].plot(ep, col("return"), lw=0.7, alpha=0.5, label="episode")
    if len(ep) >= 15:
        ax[0].plot(ep[14:], np.convolve(col("return"), np.ones(15) / 15, "valid"), lw=1.5, label="mean of 15")
    ax[0].set_ylabel("cumulative reward")
    ax[0].legend(fontsize=8)
    ax[1].plot(ep, col("sr15"))
    ax[1].set_ylabel("success rate (last 15)")
    ax[1].set_ylim(-0.05, 1.05)
    ax[2].plot(ep, col("e_r_mm"))
    ax[2].set_ylabel("guidance error range E_r (mm)")
    ax[3].plot(ep, col("ex_r_mm"))
    ax[3].set_ylabel("exploration range Ex_r (mm)")
    for x in ax:
        x.set_xlabel("episode")
        x.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------- the results report (issue 4)
# The paper's numbers, next to which ours stand. Table 1: simulated peg, 20 trials after 200 episodes.
VISUAL_PAPER_CRITICS = "visual (critic multimodal)"     # our visual row's critics are privileged (README)
PAPER_TABLE1 = {"two-step": "0.533, 19.00 +- 5.75, 13.21 / 13.22 / 9.78",
                "vanilla": "did not learn", "visual": "did not learn", VISUAL_PAPER_CRITICS: "did not learn",
                "ours": "1.00, 2.41 +- 1.93, 12.14 / 6.92 / 3.23"}
# Table 2 (real robot), success rate at 5/10/15/20 mm: the rows that the paper's layout pins down
PAPER_TABLE2 = {("peg", "train"): "1.00 / 1.00 / 1.00 / 0.80", ("peg", "loc-1"): "1.00 / 1.00 / 0.90 / 0.75",
                ("gear", "train"): "1.00 / 1.00 / 0.95 / 0.70"}
UNSEEN = ("loc-1", "bg-objects")           # our stand-ins for the paper's 'unseen 1' (location), 'unseen 2' (background)
LEVELS = (5.0, 10.0, 15.0, 20.0)


def load_run(d):
    cfg = read_config(d)
    with open(os.path.join(d, "metrics.csv")) as f:
        rows = list(csv.DictReader(f))
    ev = read_json(os.path.join(d, "eval.json")) if os.path.exists(os.path.join(d, "eval.json")) else None
    m = {k: np.array([float(r[k]) for r in rows]) for k in ("episode", "return", "success", "sr15", "e_r_mm",
                                                             "ex_r_mm", "elapsed_s")}
    return {"dir": d, "cfg": cfg, "m": m, "eval": ev}


def method_of(cfg):
    """'ours', 'vanilla', 'visual' or the ablation variant a run trained, plus any learning setting
    that differs from the defaults (so that runs are grouped only with their like)."""
    if cfg.get("vanilla"):
        name = "vanilla"
    elif cfg["obs"] == "v":
        name = "visual"
    elif (cfg["obs"], cfg["curriculum"], cfg["roi"], cfg["error_mm"]) == ("ts-ptv", "adaptive", "task", 20.0):
        name = "ours"
    else:
        name = f"{cfg['obs']}, {cfg['curriculum']} to {cfg['error_mm']:g} mm, roi {cfg['roi']}"
    default = Args()
    changed = [f"{k} {cfg[k]}" for k in ("critic", "updates", "warmup", "batch", "lr", "gamma", "aux_weight",
                                         "prior_weight", "target_entropy")
               if k in cfg and cfg[k] != getattr(default, k)]
    return name + (f" ({', '.join(changed)})" if changed else "")


def command_of(cfg):
    """The training command that reproduces a run: the flags whose values differ from the defaults."""
    default, flags = Args(), ["python tacrl.py"]
    for k, v in cfg.items():
        if k in ("run_dir", "threads", "device", "resume", "seeds", "archive", "report", "report_dir") or not hasattr(default, k):
            continue
        if v != getattr(default, k) or k == "task":
            flags.append(f"--{k.replace('_', '-')}" + ("" if v is True else f" {v:g}" if isinstance(v, float) else f" {v}"))
    return " ".join(flags)


def bootstrap_band(curves, n=1000, seed=0):
    """curves: seeds x episodes -> mean and the 95% bootstrap interval of the mean over seeds."""
    c = np.array([x[:min(map(len, curves))] for x in curves])
    rng = np.random.default_rng(seed)
    boots = c[rng.integers(0, len(c), (n, len(c)))].mean(1)
    return c.mean(0), np.percentile(boots, 2.5, 0), np.percentile(boots, 97.5, 0)


def smooth(x, k=15):
    """Moving average over k episodes (shorter at the start), as the paper smooths its curves."""
    c = np.cumsum(np.insert(np.asarray(x, float), 0, 0.0))
    n = np.minimum(np.arange(1, len(x) + 1), k)
    return (c[1:] - c[np.arange(1, len(x) + 1) - n]) / n


CURVES = {"return": "cumulative reward (mean of 15)", "sr15": "success rate (last 15)",
          "e_r_mm": "guidance error range E_r (mm)", "ex_r_mm": "exploration range Ex_r (mm)"}


def plot_groups(groups, keys, out, title):
    """One panel per key; in each, one line (mean over seeds) and band (95% bootstrap over seeds)
    per group of runs, against episode (the paper's Fig. 9-11)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.6), squeeze=False)
    colours = plt.get_cmap("tab10").colors   # after 10 groups the colours come round again, dashed
    for ax, key in zip(axs[0], keys):
        for i, (name, runs) in enumerate(groups.items()):
            curves = [smooth(r["m"][key]) if key == "return" else r["m"][key] for r in runs]
            mean, lo, hi = bootstrap_band(curves)
            ep = np.arange(1, len(mean) + 1)
            seeds = sorted({r["cfg"]["seed"] for r in runs})
            line, = ax.plot(ep, mean, lw=1.2, color=colours[i % len(colours)], ls="--" if i >= 10 else "-", label=f"{name} (seed{'s' * (len(seeds) > 1)} {', '.join(map(str, seeds))})")
            if len(runs) > 1:
                ax.fill_between(ep, lo, hi, alpha=0.2, color=line.get_color())
        ax.set_xlabel("episode")
        ax.set_ylabel(CURVES[key])
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    if len(groups) <= 4:
        axs[0][0].legend(fontsize=7)
    else:                                  # many curves: the legend to the right, off the data
        fig.legend(*axs[0][0].get_legend_handles_labels(), fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)


def plot_context_bars(bars, out, title):
    """Fig. 12: mean cumulative reward (over the evaluated error ranges and trials) per context,
    one group of bars per ROI. bars: {roi label: {context: [mean, std]}}."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    contexts = list(next(iter(bars.values())))
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    w = 0.8 / len(contexts)
    for k, ctx in enumerate(contexts):
        xs = np.arange(len(bars)) + (k - (len(contexts) - 1) / 2) * w
        ax.bar(xs, [bars[r][ctx][0] for r in bars], w, yerr=[bars[r][ctx][1] for r in bars], capsize=3, label=ctx)
    ax.set_xticks(np.arange(len(bars)))
    ax.set_xticklabels(list(bars))
    ax.axhline(0, color="k", lw=0.6)
    ax.set_ylabel("cumulative reward per episode")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_views(task, rois, out, error=(0.015, -0.010, 0.0, 0.05)):
    """What the policy sees: the first image of an episode with the same error in each context
    (columns) through each ROI (rows), so that Fig. 12's bars can be read against the pixels."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    contexts = ("train",) + UNSEEN
    fig, ax = plt.subplots(len(rois), len(contexts), figsize=(2.2 * len(contexts), 2.3 * len(rois)), squeeze=False)
    for i, roi in enumerate(rois):
        for j, ctx in enumerate(contexts):
            env = sim.AssemblyEnv(task, ctx, roi=roi)
            try:
                obs, _ = env.reset(options={"error": np.array(error)})
            finally:
                env.close()
            ax[i, j].imshow(obs["image"], cmap="gray", vmin=0, vmax=255)   # (80, 80) uint8
            ax[i, j].set_xticks([])
            ax[i, j].set_yticks([])
            ax[i, j].set_title(f"{ctx}, ROI {roi}", fontsize=8)
    fig.suptitle(f"{task}: the 80x80 image at X^_i, error {error[0] * 1000:g} / {error[1] * 1000:g} mm", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


OBS_NAMES = {"pt": "P-T", "ts-pt": "Time-series P-T", "ts-ptv": "Time-series P-T-V"}


def families(cfg):
    """The paper's comparisons a run takes part in: {figure family: curve label}. Only runs with
    the default learning settings (method_of without a suffix) are compared."""
    name = method_of(cfg)
    if name == VISUAL_PAPER_CRITICS:    # the paper's own visual baseline: its critics see what the actor sees
        return {"methods": name}
    if "(" in name:
        return {}
    ours_but = lambda **kw: all(cfg[k] == v for k, v in {"obs": "ts-ptv", "curriculum": "adaptive", "roi": "task",
                                                         "error_mm": 20.0, "vanilla": False, **kw}.items())
    fam = {}
    if name in ("ours", "vanilla", "visual"):
        fam["methods"] = name
    if cfg["curriculum"] == "ex10" and cfg["roi"] == "task" and not cfg.get("vanilla"):
        fam["obs"] = OBS_NAMES.get(cfg["obs"], cfg["obs"])
    if ours_but(curriculum=cfg["curriculum"], error_mm=cfg["error_mm"]) and cfg["curriculum"] != "ex10" and (
            cfg["curriculum"] in ("none", "adaptive") or cfg["error_mm"] == 30.0):   # ours: adaptive at 20 mm
        fam["curriculum"] = ("no curriculum" if cfg["curriculum"] == "none" else f"curriculum {cfg['curriculum']}") \
            + f", {cfg['error_mm']:g} mm"
    if ours_but(roi=cfg["roi"]):
        fam["roi"] = "task attention (Eq. 11)" if cfg["roi"] == "task" else f"ROI {cfg['roi']}"
    return fam


FAMILIES = {   # family: (title, curves, the paper's figure)
    "methods": ("ours against the learned baselines", ("return", "sr15", "e_r_mm"), "Table 1"),
    "obs": ("observation ablation: Ex_r held at 10 mm, E_r adaptive", ("sr15", "e_r_mm"), "Fig. 9"),
    "curriculum": ("curriculum ablation", ("return", "sr15", "e_r_mm", "ex_r_mm"), "Fig. 10"),
    "roi": ("ROI ablation", ("return", "sr15", "e_r_mm"), "Fig. 11"),
}


def eval_cached(run, context, levels=LEVELS, episodes=20, log=print):
    """Table-2 rows of a run's policy in `context`, evaluated once and kept in the run dir (the
    training context's come from eval.json when it holds the same levels)."""
    cfg = run["cfg"]
    act = load_policy(os.path.join(run["dir"], "policy.pt"), cfg["task"])
    plan = [(mm, round(sim.exploration_range(mm / 1000, act.ex_r) * 1000, 3)) for mm in levels]   # (E_r, Ex_r), mm
    tag = "" if tuple(levels) == LEVELS else "-" + "-".join(f"{mm:g}" for mm in levels) + "mm"
    path = os.path.join(run["dir"], f"eval-{context}{tag}.json")
    for rows in ([run["eval"]["rows"]] if context == "train" and run["eval"] else []) + \
            ([read_json(path)] if os.path.exists(path) else []):     # eval.json, then this cache
        if [(r["error_mm"], r.get("ex_r_mm")) for r in rows] == plan and rows[0]["episodes"] == episodes:
            return rows
    log(f"  evaluating {run['dir']} in {context} at {', '.join(f'{mm:g}' for mm in levels)} mm")
    env = policy_env(cfg["task"], act, context, cfg["roi"], cfg["clearance_mm"])
    try:
        rows = evaluate_levels(env, act, levels, episodes, EVAL_SEED + cfg["seed"])
    finally:
        env.close()
    with open(path, "w") as f:
        json.dump(rows, f, indent=2)
    return rows


def cell(row, k, f="{:.2f}"):
    v = row.get(k)
    return "-" if v is None else f"{f.format(v[0])} +- {f.format(v[1])}"


def behaviour_plot(run, out, error_mm=10.0, seed=0):
    """Fig. 16: one episode of a policy, observations and actions scaled to [-1, 1] per channel,
    with its phases: free motion (no contact), search after contact, insertion (tip in the hole)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import torch
    cfg = run["cfg"]
    act = load_policy(os.path.join(run["dir"], "policy.pt"), cfg["task"])
    env = policy_env(cfg["task"], act, roi=cfg["roi"], e_r_mm=error_mm)
    feats, poses, wrenches, acts, phase = [], [], [], [], []

    def policy_step(obs):                       # the policy, recording its image features and actions
        with torch.no_grad():
            img = torch.as_tensor(obs["image"][None])
            feats.append(act.enc.image(img)[0].numpy() if act.enc.image is not None else np.zeros(6))
        acts.append(act(obs))
        return acts[-1]

    def on_step(obs, r, info):
        poses.append(info["goal_offset"])
        wrenches.append(info["f_world"])
        phase.append(2 if info["depth"] > 0.001 else 1 if np.abs(info["f_world"][:3]).max() > 0.5 else 0)
    term, _, _ = sim.run_episode(env, policy_step, seed=EVAL_SEED * 7 + seed, on_step=on_step)
    env.close()
    phase = np.maximum.accumulate(phase)        # free -> search after contact -> insertion
    norm = lambda x: np.array(x) / np.maximum(np.abs(np.array(x)).max(0), 1e-9)   # noqa: E731
    panels = [("image features", norm(feats)), ("relative pose X - X_g (x, y, z, yaw)", norm(poses)),
              ("wrench (Fx, Fy, Fz, Tx, Ty, Tz)", norm(wrenches)), ("action (F_d, 6-D)", np.array(acts))]
    fig, ax = plt.subplots(len(panels), 1, figsize=(7, 8), sharex=True)
    t = np.arange(1, len(acts) + 1)
    for x, (name, y) in zip(ax, panels):
        x.plot(t, y, lw=1)
        for ph, colour in ((0, "gold"), (1, "red"), (2, "green")):
            if (phase == ph).any():
                x.axvspan(t[phase == ph][0] - 0.5, t[phase == ph][-1] + 0.5, color=colour, alpha=0.12)
        x.set_ylabel(name, fontsize=8)
        x.set_ylim(-1.1, 1.1)
    ax[-1].set_xlabel("policy step (0.2 s); yellow: free motion, red: search after contact, green: insertion")
    fig.suptitle(f"one episode, {cfg['task']}, {error_mm:g} mm error range, success {bool(term)}", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def match_runs(patterns, flag):
    """The run directories (config.json + metrics.csv) that comma-separated glob patterns match."""
    import glob
    dirs = sorted({d for p in patterns.split(",") for d in glob.glob(p.strip())
                   if os.path.exists(os.path.join(d, "config.json")) and os.path.exists(os.path.join(d, "metrics.csv"))})
    if not dirs:
        raise ArgError(f"--{flag} {patterns!r}: no run directory (config.json + metrics.csv) matches")
    return dirs


RESULTS_DIR = "results"       # the archived runs the report is built from; the repository keeps them
ARCHIVED = ("config.json", "metrics.csv", "policy.pt", "curves.png", "train.log")    # and eval*.json


def archive_runs(patterns, dest=RESULTS_DIR, log=print):
    """Copy what the report reads of each finished run (eval.json written) to dest/<run name>/: under
    1 MB a run (policy.pt), where the checkpoint and the replay buffer that stay behind are hundreds of MB.
    A run dir lives on one machine; the archive travels with the repository, so the report can be
    regenerated from a fresh clone. Returns the archived directories."""
    import shutil
    done = []
    for d in match_runs(patterns, "archive"):
        if not os.path.exists(os.path.join(d, "eval.json")):
            log(f"  {d}: not finished (no eval.json), not archived")
            continue
        to = os.path.join(dest, os.path.basename(os.path.normpath(d)))
        os.makedirs(to, exist_ok=True)
        names = [f for f in os.listdir(d) if f in ARCHIVED or (f.startswith("eval") and f.endswith(".json"))]
        for f in names:
            shutil.copy2(os.path.join(d, f), os.path.join(to, f))
        log(f"  {d} -> {to} ({', '.join(sorted(names))})")
        done.append(to)
    if not done:
        raise ArgError(f"--archive {patterns!r}: no finished run (with eval.json) to archive")
    return done


def write_report(patterns, out_dir="docs", log=print):
    """docs/RESULTS.md and its figures from run directories (glob patterns, comma-separated)."""
    runs = [load_run(d) for d in match_runs(patterns, "report")]
    os.makedirs(out_dir, exist_ok=True)
    for f in os.listdir(out_dir):          # an earlier report's figures, which these runs may not redraw
        if f.startswith("fig-") and f.endswith(".png"):
            os.remove(os.path.join(out_dir, f))
    md = ["# Results", "", f"Regenerated by `python tacrl.py --report \"{patterns}\"` from {len(runs)} run "
          "directories. Every number below was measured by running this code on a 2-core CPU machine; "
          "the paper's numbers stand beside ours.", "", "## The runs", "",
          "| run | command | method | episodes | minutes (threads) | final E_r (mm) | max E_r (mm) | eval SR 5/10/15/20 mm |",
          "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        ev = r["eval"]
        srs = " / ".join(f"{row['success_rate']:.2f}" for row in ev["rows"]) if ev else "not finished"
        if ev and tuple(row["error_mm"] for row in ev["rows"]) != LEVELS:   # e.g. a 30 mm run's 10/20/30
            srs += " (at " + "/".join(f"{row['error_mm']:g}" for row in ev["rows"]) + " mm)"
        md.append(f"| `{r['dir']}` | `{command_of(r['cfg'])}` | {method_of(r['cfg'])} | "
                  f"{len(r['m']['episode'])} | {r['m']['elapsed_s'][-1] / 60:.1f} ({r['cfg'].get('threads') or 'all'}) | "
                  f"{r['m']['e_r_mm'][-1]:.1f} | {r['m']['e_r_mm'].max():.1f} | {srs} |")
    # -- Table 1: peg at 20 mm
    md += ["", "## Table 1: peg-in-hole at 20 mm error (20 trials, evaluation seeds never used in training)", "",
           "| method | training episodes | SR | CT (s) | peak contact force x / y / z (N) | cumulative reward | "
           "paper: SR, CT, force x/y/z |", "|---|---|---|---|---|---|---|"]
    path = os.path.join(out_dir, "two-step-peg-20mm.json")
    if os.path.exists(path):
        ts_row = read_json(path)
    else:
        log("evaluating the two-step baseline (peg, 20 mm, 20 episodes)")
        env = sim.AssemblyEnv("peg", e_r=0.02)
        ts = TwoStep(env)
        ts.calibrate()
        ts_row = evaluate(env, ts, 20, EVAL_SEED, log=lambda *_: None)
        env.close()
        with open(path, "w") as f:
            json.dump(ts_row, f, indent=2)
    table1 = [("two-step", [ts_row], "-")]
    for name in ("vanilla", "visual", VISUAL_PAPER_CRITICS, "ours"):
        done = [r for r in runs if r["cfg"]["task"] == "peg" and method_of(r["cfg"]) == name and r["eval"]]
        rows = [row for r in done for row in r["eval"]["rows"] if row["error_mm"] == 20.0]
        table1.append((name, rows, ", ".join(sorted({str(len(r["m"]["episode"])) for r in done}))))
    for name, rows, episodes in table1:
        if not rows:
            md.append(f"| {name} | | not run | | | | {PAPER_TABLE1[name]} |")
            continue
        sr = np.array([x["success_rate"] for x in rows])
        if len(rows) == 1:
            ct = cell(rows[0], "completion_time_s")
        else:                              # the seeds' mean completion times, averaged
            cts = [x["completion_time_s"][0] for x in rows if x["completion_time_s"]]
            ct = f"{np.mean(cts):.2f} (mean of seeds)" if cts else "-"
        fx = " / ".join(f"{np.mean([x[k][0] for x in rows]):.2f}"
                        for k in ("contact_force_x_N", "contact_force_y_N", "contact_force_z_N"))
        cr = f"{np.mean([x['cumulative_reward'][0] for x in rows]):.1f}"
        srs = f"{sr.mean():.2f}" + (f" +- {sr.std():.2f} ({len(rows)} seeds)" if len(rows) > 1 else "")
        md.append(f"| {name} | {episodes} | {srs} | {ct} | {fx} | {cr} | {PAPER_TABLE1[name]} |")
    # -- Table 2: ours in the training and unseen contexts
    md += ["", "## Table 2: our policy in the training context and two unseen ones", "",
           "Success rate / completion time (s) / cumulative reward at 5, 10, 15, 20 mm error, 20 trials each.", "",
           "| task | context | 5 mm | 10 mm | 15 mm | 20 mm | paper SR (real robot) |", "|---|---|---|---|---|---|---|"]
    for task in ("peg", "gear"):
        ours = [r for r in runs if r["cfg"]["task"] == task and method_of(r["cfg"]) == "ours" and r["eval"]]
        if not ours:
            md.append(f"| {task} | - | not run | | | | |")
            continue
        best = ours[0]                      # the first seed stands for the method in the unseen contexts
        for ctx in ("train",) + UNSEEN:
            rows = eval_cached(best, ctx, log=log)
            cells = [f"{x['success_rate']:.2f} / {cell(x, 'completion_time_s', '{:.1f}').split(' +-')[0]} / "
                     f"{x['cumulative_reward'][0]:.1f}" for x in rows if x["error_mm"] in LEVELS]
            md.append(f"| {task} | {ctx} | {' | '.join(cells)} | {PAPER_TABLE2.get((task, ctx), '-')} |")
    # -- curriculum ablation (Fig. 10) in numbers: how soon each run reached its final range, how it did there
    for task in ("peg", "gear"):
        fam = sorted(((families(r["cfg"])["curriculum"], r) for r in runs if r["cfg"]["task"] == task
                      and "curriculum" in families(r["cfg"]) and r["eval"]), key=lambda x: x[0])
        if len({label for label, _ in fam}) < 2:
            continue
        md += ["", f"## Curriculum ablation, {task} (the paper's Fig. 10)", "",
               "Training: the first episode whose E_r reached the run's final error range, and success and return "
               "over the last 50 episodes. Evaluation: 20 trials at that range.", "",
               "| curriculum | run | first episode at the final E_r | training success, last 50 | training return, "
               "last 50 | eval SR | eval CT (s) |", "|---|---|---|---|---|---|---|"]
        for label, r in fam:
            m, mm = r["m"], r["cfg"]["error_mm"]
            at = np.flatnonzero(m["e_r_mm"] >= mm - 1e-6)
            row = next((x for x in r["eval"]["rows"] if x["error_mm"] == mm), None) \
                or eval_cached(r, "train", levels=(mm,), log=log)[0]
            first = int(m["episode"][at[0]]) if len(at) else "never"
            md.append(f"| {label} | `{r['dir']}` | {first} of {len(m['episode'])} | "
                      f"{m['success'][-50:].mean():.2f} | {m['return'][-50:].mean():.1f} | "
                      f"{row['success_rate']:.2f} | {cell(row, 'completion_time_s').split(' +-')[0]} |")
        md += ["", "The paper (training curves, 300 episodes): without curriculum, 10 mm reaches SR 0.9 and reward "
               "70, 20 mm SR 0.6 and reward 20, 30 mm less; at 30 mm every curriculum beats no curriculum, g2-c10 "
               "learns faster than g2-c30, and g2-c2 behaves like g2-c10."]
    # -- learning curves: one figure per comparison of the paper and task
    figs = []
    for task in ("peg", "gear"):
        groups = {}
        for r in runs:
            if r["cfg"]["task"] == task:
                groups.setdefault(method_of(r["cfg"]), []).append(r)
        if groups:                         # every run of the task, grouped by what it trained
            name = f"fig-{task}-runs.png"
            plot_groups(groups, ("sr15", "e_r_mm"), os.path.join(out_dir, name), f"{task}: every run")
            figs.append((name, f"{task}: every run, grouped by method and setting"))
        for fam, (title, keys, paper_fig) in FAMILIES.items():
            groups = {}
            for r in runs:
                label = families(r["cfg"]).get(fam)
                if r["cfg"]["task"] == task and label:
                    groups.setdefault(label, []).append(r)
            if not groups or (fam != "methods" and len(groups) < 2):
                continue
            name = f"fig-{task}-{fam}.png"
            plot_groups(groups, keys, os.path.join(out_dir, name), f"{task}: {title}")
            figs.append((name, f"{task}, {title} (the paper's {paper_fig}): mean over seeds, 95% bootstrap band "
                               "where there are several"))
    # -- context generalization (Fig. 12): task-attention ROI against the full view, mean cumulative reward
    for task in ("peg", "gear"):
        bars = {}
        for roi in ("task", "full"):
            r = next((r for r in runs if r["cfg"]["task"] == task and r["eval"]
                      and families(r["cfg"]).get("roi") and r["cfg"]["roi"] == roi), None)
            if r is None:
                continue
            bars[families(r["cfg"])["roi"]] = by_ctx = {}
            for ctx in ("train",) + UNSEEN:
                cr = np.array([x["cumulative_reward"][0] for x in eval_cached(r, ctx, log=log)])
                by_ctx[ctx] = [float(cr.mean()), float(cr.std())]
        if len(bars) == 2:
            name = f"fig-{task}-contexts.png"
            plot_context_bars(bars, os.path.join(out_dir, name), f"{task}: training context and two unseen ones")
            figs.append((name, f"{task}: mean cumulative reward over 5/10/15/20 mm (20 trials each) in the training "
                               "context and two unseen ones, task-attention ROI against the full view (the paper's "
                               "Fig. 12; bars: spread over the four error ranges)"))
            plot_views(task, ("task", "full"), os.path.join(out_dir, f"fig-{task}-views.png"))
            figs.append((f"fig-{task}-views.png", f"{task}: what the policy sees at the start of an episode in each "
                                                  "context, through the task-attention ROI and the full view"))
            md += ["", f"## Context generalization, {task} (the paper's Fig. 12)", "",
                   "Mean cumulative reward per episode over 5/10/15/20 mm, 20 trials each.", "",
                   "| ROI | " + " | ".join(("train",) + UNSEEN) + " |", "|---" * (1 + len(UNSEEN) + 1) + "|"]
            md += [f"| {roi} | " + " | ".join(f"{v[ctx][0]:.1f}" for ctx in v) + " |" for roi, v in bars.items()]
            md += ["", "The paper (real robot, average cumulative reward): task attention 61.19 -> 54.73 (new "
                   "background), 69.23 -> 46.46 (new location); full view 61.12 -> -23.06 and 59.51 -> -14.65."]
    ours_peg = [r for r in runs if r["cfg"]["task"] == "peg" and method_of(r["cfg"]) == "ours" and r["eval"]]
    if ours_peg:
        behaviour_plot(ours_peg[0], os.path.join(out_dir, "fig-behaviour.png"))
        figs.append(("fig-behaviour.png", "one episode of our peg policy at 10 mm error (the paper's Fig. 16)"))
    md += ["", "## Figures", ""]
    for name, caption in figs:
        md += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    notes = os.path.join(out_dir, "results-notes.md")     # the hand-written reading of these numbers
    if os.path.exists(notes):
        with open(notes) as f:
            md += ["", f.read().strip()]
    with open(os.path.join(out_dir, "RESULTS.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    log(f"wrote {out_dir}/RESULTS.md and {len(figs)} figures")
    return 0


# ---------------------------------------------------------------- several seeds
def strip_flag(argv, flag):
    """argv without `flag VALUE` / `flag=VALUE`."""
    out, skip = [], False
    for x in argv:
        if skip:
            skip = False
        elif x == flag:
            skip = True
        elif not x.startswith(flag + "="):
            out.append(x)
    return out


def seed_commands(a, argv, cores=None):
    """--seeds: how many processes at once, and (seed, run dir, command line) for each seed."""
    seeds = [int(x) for x in a.seeds.split(",")]
    cores = cores or os.cpu_count() or 1
    parallel = min(len(seeds), cores)
    base = argv
    for flag in ("--seeds", "--seed", "--run-dir", "--threads"):
        base = strip_flag(base, flag)
    jobs = []
    for s in seeds:
        run_dir = re.sub(r"-s\d+$", "", a.run_dir) + f"-s{s}"
        jobs.append((s, run_dir, [sys.executable, os.path.abspath(__file__), *base, "--seed", str(s),
                                  "--run-dir", run_dir, "--threads", str(a.threads or max(1, cores // parallel))]))
    return parallel, jobs


def train_seeds(a, argv):
    """--seeds: one `tacrl.py ... --seed S` process per seed, at most one per core at a time, each
    with torch on cores // parallel threads (two torch processes spinning on the same cores slow each
    other down many times over). Each run is an ordinary run dir: resumable on its own."""
    import subprocess
    parallel, jobs = seed_commands(a, argv)
    todo, running, t0, shown = list(jobs), {}, time.time(), 0.0
    while todo or running:
        while todo and len(running) < parallel:
            s, run_dir, cmd = todo.pop(0)
            os.makedirs(run_dir, exist_ok=True)
            running[s] = (subprocess.Popen(cmd, stdout=open(os.path.join(run_dir, "train.log"), "w"),
                                           stderr=subprocess.STDOUT), run_dir)
            print(f"seed {s}: started, {run_dir}/train.log", flush=True)
        time.sleep(5)
        status = []
        for s, (proc, run_dir) in list(running.items()):
            with open(os.path.join(run_dir, "train.log")) as f:
                last = [ln for ln in f.read().splitlines() if ln.startswith("ep ")]
            status.append(f"s{s} {last[-1].split()[1] if last else '-'}")
            if proc.poll() is not None:
                del running[s]
                print(f"seed {s}: finished with exit code {proc.returncode} ({fmt_time(time.time() - t0)})", flush=True)
        if status and time.time() - shown > 60:
            shown = time.time()
            print(f"[{fmt_time(time.time() - t0)}] episodes: {'  '.join(status)}", flush=True)
    return 0


# ---------------------------------------------------------------- the command line
def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        a = parse_args(argv)
        if a.archive:
            archive_runs(a.archive)
            return 0
        if a.report:
            return write_report(a.report, a.report_dir)
        if a.seeds:
            return train_seeds(a, argv)
        if not a.eval:
            print("config:", asdict(a))
            train(a)
            return 0
        act = None if a.eval in BASELINES else load_policy(a.eval, a.task, pick_device(a.device))
        if act is not None and act.roi != a.roi:      # its encoder learned that view, not another
            raise ArgError(f"--eval {a.eval!r}: this policy was trained with --roi {act.roi}, not {a.roi}")
    except ArgError as e:
        print(f"tacrl: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        where = f"; continue with --resume {a.run_dir}" if "a" in locals() and not a.eval else ""
        print(f"\ninterrupted: every finished episode is saved{where}", file=sys.stderr)
        return 130
    print("config:", asdict(a))
    env = policy_env(a.task, act, a.context, a.roi, a.clearance_mm, a.error_mm, a.gui)
    if a.eval == "initial":
        act = lambda obs: np.zeros(6)          # noqa: E731  the hand-designed policy alone, F_d = 0
    elif a.eval == "two-step":
        act = TwoStep(env)
        print(f"two-step: calibrated the image -> offset map, median error {act.calibrate() * 1000:.2f} mm")
    video = None
    if a.video:
        import cv2
        frame = env.world.render_external()
        video = cv2.VideoWriter(a.video, cv2.VideoWriter_fourcc(*"mp4v"), sim.POLICY_HZ, frame.shape[1::-1])
    name = a.eval if a.eval in BASELINES else "TA-MRP"
    try:
        row = evaluate(env, act, a.episodes, EVAL_SEED + a.seed, video)   # the seeds of eval.json and the report
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        if video is not None:
            video.release()
        env.close()
    row.update({"task": a.task, "policy": a.eval, "error_mm": a.error_mm, "ex_r_mm": round(env.ex_r * 1000, 3),
                "context": a.context, "roi": a.roi, "seed": a.seed})
    print(format_row(f"{name} {a.task} {a.error_mm:g}mm", row))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(row, f, indent=2)
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
