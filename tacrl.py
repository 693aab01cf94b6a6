"""tacrl.py: Algorithm 1 of Wang et al., "Task attention-based multimodal fusion and curriculum residual
learning for context generalization in robotic assembly" (Applied Intelligence, 2024). The residual TA-MRP
(policy.py) learns F_d on top of the hybrid policy (control.py, sim.py) while the adaptive curriculum of
Eq. 16 (curriculum.py) widens the error range; then its evaluation (evaluate.py, Tables 1-2):

    python tacrl.py --task peg                            # train, then evaluate at 5/10/15/20 mm
    python tacrl.py --resume runs/peg-ts-ptv-adaptive-s0  # continue (with --train-episodes N: extend)
    python tacrl.py --task peg --eval runs/peg-ts-ptv-adaptive-s0/policy.pt --error-mm 20 --video ep.webm
    python tacrl.py --task peg --eval initial --error-mm 0      # the hand-designed policy alone
    python tacrl.py --task peg --eval two-step --error-mm 20    # the classical baseline (baselines.py)

The file reads top to bottom: the run's config (every flag, once), Algorithm 1 (train), then `main`. The
command line's checks and --eval are command.py's (cli.py: what every command shares). What a run directory
holds is rundir.py's; several seeds and the paper's experiments at once: tools/sweep.py.
"""
import os
import signal
import sys
from dataclasses import dataclass, replace
from typing import ClassVar

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130, not a traceback
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\ntacrl: interrupted\n"), os._exit(130)))

try:
    import tacrl_flat  # noqa: E402, F401  (first: where another package shadows one of our modules, one line says so)
except ImportError as e:
    if __name__ != "__main__":
        raise
    sys.exit(str(e))

import numpy as np  # noqa: E402
import torch  # noqa: E402

import cli  # noqa: E402
import command  # noqa: E402
import contexts  # noqa: E402
import curriculum  # noqa: E402
import evaluate  # noqa: E402
import policy  # noqa: E402
import rundir  # noqa: E402
import sim  # noqa: E402
from cli import ArgError, opt  # noqa: E402


def train_opt(*args, **kw):                       # a flag for training only (refused with --eval)
    return opt(*args, mode="train", **kw)


@dataclass
class Config:
    # the task
    task: str = opt("peg", "peg (16 mm peg, 0.1 mm clearance) or gear (Sec. 5.1.1)", ("peg", "gear"))
    seed: int = opt(0, "seeds the errors, the networks and the replay sampling", bounds=(0, 2 ** 31 - 1))
    error_mm: float = opt(20.0, "error range E_r in mm (Eq. 13-15): evaluated, or the curriculum's final one",
                          bounds=(0.0, 30.0))
    context: str = opt("train", f"board location and background (Sec. 5.1.4: {', '.join(contexts.CONTEXTS)}), or "
                                f"FAMILY:SEED, one scene of a family ({', '.join(contexts.FAMILIES)}), "
                                "FAMILY:test, a held-out one each episode, or FAMILY:train, one of training's side",
                       contexts.ContextNames())
    roi: str = opt("task", "image window: task (Eq. 11's task attention) or a window of Fig. 11",
                   ("task", *sim.ROI_PRESETS))
    clearance_mm: float = opt(0.1, "diametral clearance of the peg or the gear's bore, mm", bounds=(0.0, 2.0),
                              open_bounds=True)
    # the paper's protocol (training only)
    train_episodes: int = train_opt(300, "max-episodes of Algorithm 1: the most a run trains", bounds=(1, None))
    stop_held: int = train_opt(30, "stop when learned: after this many episodes at the final range, every 10 the "
                                   "greedy policy tries 20 there; 19 wins stop the run (0: never); with --randomize, "
                                   "every 30, and each family's training side must hold too (9 of 10 scenes each, "
                                   "then 27 of 30)",
                               bounds=(0, None))
    obs: str = train_opt("ts-ptv", "observations (Fig. 9); v: the visual baseline; ts-ptk: keypoint RL (the hole "
                                   "found in the image by a detector, with the pose and wrench histories; peg)",
                         policy.OBS_KINDS)
    curriculum: str = train_opt("adaptive", "error curriculum (Eq. 16, Fig. 10); ex10: Fig. 9's", curriculum.KINDS)
    vanilla: bool = train_opt(False, "the vanilla baseline, without a base policy: no trajectory, no spring, no "
                                     "stiffness from the estimated poses; F_d alone moves the tool")
    updates: int = train_opt(200, "SAC gradient steps after each episode (Sec. 5.1.1: 200)", bounds=(0, None))
    warmup: int = train_opt(20, "random-action episodes before the first update (the authors' loop: 20)",
                            bounds=(0, None))
    # SAC
    critic: str = train_opt("privileged", "privileged: the critics also read X - X_g; multimodal: they read the "
                                          "actor's observation as the paper's do, and (ours) the time, the "
                                          "curriculum's ranges and LayerNorms (README difference 13)",
                            ("privileged", "multimodal"))
    batch: int = train_opt(64, "SAC batch size", bounds=(1, None))
    buffer: int = train_opt(50000, "replay capacity, transitions (at least an episode and a batch)", bounds=(1, None))
    lr: float = train_opt(3e-4, "Adam step size of actor, critics and temperature", bounds=(0, 1), open_bounds=True)
    gamma: float = train_opt(0.95, "discount (0.99 let the critics thrash: README difference 10)", bounds=(0, 1),
                             open_bounds=True)
    target_entropy: float = train_opt(-6.0, "SAC's entropy target (the usual -|A|)")
    # ours, beyond the paper
    robust: bool = train_opt(False, "the robust option: trains among every family's training scenes (--randomize "
                                    "all but place, which mixed draws), with --image-norm image and --tilt-deg 1, "
                                    "up to 600 episodes, and stops when it holds in each (a flag given beside it wins)")
    augment: float = train_opt(0.0, "image jitter s: brightness, contrast x U(1-s, 1+s) (README difference 17)",
                               bounds=(0, 1))
    randomize: str = train_opt("", "draw each episode's scene from these families' training scenes, comma-separated "
                                   f"(domain randomization: {', '.join(contexts.FAMILIES)})")
    image_norm: str = train_opt("fixed", "the image's grey levels as the encoder reads them: x / 255 - 0.5 (fixed), or "
                                         "each image standardised by its own mean and spread (image; ours)",
                                policy.IMAGE_NORMS)
    tilt_deg: float = train_opt(0.0, "board tilt the stiffness about x and y leaves room for, deg (Eq. 8's range "
                                      "besides sim.EX_ROT; ours: 1 covers the touch family)", bounds=(0, 10))
    # evaluation
    eval: str = opt("", "evaluate, not train: initial (F_d = 0), two-step (baselines.py), a policy.pt, or a run's "
                        "ckpt.pt (its policy at its last episode)")
    episodes: int = opt(20, "evaluation episodes a level (the paper: 20 test trials)", bounds=(1, None))
    eval_levels: str = train_opt("5,10,15,20", "error ranges (mm) evaluated after training (Table 2)")
    json: str = opt("", "also write the evaluation row to this new JSON file", mode="eval")
    video: str = opt("", "record the first evaluation episode from an external camera to this new .webm (VP9) or "
                         ".mp4 (H.264, where OpenCV has it): a browser plays either", mode="eval")
    # files and the machine
    resume: str = train_opt("", "continue the run in this directory as its config.json says")
    run_dir: str = train_opt("", "run directory, new or empty (default: runs/<task>-<obs>-...-s<seed>)")
    track: bool = train_opt(False, "also log to TensorBoard in <run dir>/tb: metrics.csv's columns, the losses, now "
                                   "and then the task-attention image (pip install -e '.[track]'; tensorboard "
                                   "--logdir runs)")
    device: str = opt("auto", "where torch runs", ("auto", "cpu", "cuda"))
    threads: int = opt(0, "CPU cores a run uses: an update's two halves of each batch side by side and evaluation's "
                          "episodes in two processes (2), or one after the other (1), the same numbers either way "
                          "(0: 2 where there are 2 cores)", bounds=(0, 2))
    gui: bool = opt(False, "open the PyBullet window")
    # --help lists the flags under these titles (cli.parse), and the run prints its config so (cli.format_config)
    GROUPS: ClassVar[dict] = {
        "the task (Sec. 5.1.1)": ("task", "seed", "error_mm", "context", "roi", "clearance_mm"),
        "the paper's protocol (Algorithm 1, Sec. 5.1)": ("train_episodes", "stop_held", "obs", "curriculum",
                                                         "vanilla", "updates", "warmup"),
        "SAC (Sec. 4.3.2; what the paper leaves open: README difference 10)": ("critic", "batch", "buffer", "lr",
                                                                                "gamma", "target_entropy"),
        "ours, off by default (README difference 17)": ("robust", "augment", "randomize", "image_norm", "tilt_deg"),
        "evaluation (Tables 1-2)": ("eval", "episodes", "eval_levels", "json", "video"),
        "files and the machine": ("resume", "run_dir", "track", "device", "threads", "gui"),
    }
    # what --robust sets, where the command line does not (command.parse_args)
    PRESETS: ClassVar[dict] = {"robust": {"randomize": ",".join(f for f in contexts.FAMILIES if f != "place"),
                                          "image_norm": "image", "tilt_deg": 1.0, "train_episodes": 600}}

    @property
    def families(self):
        """--randomize's families, a tuple."""
        return tuple(f for f in self.randomize.split(",") if f)

    @property
    def levels(self):
        """--eval-levels, mm, sorted."""
        return sorted({float(x) for x in self.eval_levels.split(",")})

    @property
    def tilt(self):
        """--tilt-deg in rad, as the env and policy.pt take it."""
        return float(np.radians(self.tilt_deg))


POSE_SCALE = np.array([sim.E_R_FINAL] * 3 + [sim.E_ROT_FINAL] * 3)   # m, rad: the encoders' pose units
STATE_DIM = 7                                                        # what privileged critics read (critic_state)
EXTRA_DIM = 3                                                        # multimodal critics' extras (critic_extra)
VAL_SEED, VAL_EPISODES, VAL_WINS, VAL_EVERY = 2000, 20, 19, 10   # stop when learned: 19 of 20
FAMILY_EPISODES, FAMILY_WINS, FAMILY_EVERY = 10, 9, 30               # ... and with --randomize, 9 of 10 in each family
FAMILY_CONFIRM, FAMILY_CONFIRM_WINS = 30, 27                          # ... then 27 of 30 (the same 10 and 20 more)


# ---------------------------------------------------------------- Algorithm 1
def train(cfg, log=lambda msg: print(msg, flush=True)):
    """Algorithm 1: learning context-generalized TA-MRP with ACRRL. Returns eval.json's contents."""
    command.use_cpu(cfg.device)
    torch.manual_seed(cfg.seed)
    # Lines 1-5, initialize the learning architecture: the env holds the hand-designed part of the skill (2: tau(t)
    # and K, Eq. 8-9, 14), the error range E_r (3), the ROI for E_r (4: Eq. 11, at the largest) and the reward (5)
    env = make_env(cfg, gui=cfg.gui)
    env.np_random = np.random.default_rng(cfg.seed)
    curr = curriculum.Curriculum(cfg.curriculum, final=cfg.error_mm / 1000)     # line 6: Eq. 16's parameters
    sac, stop, rng = make_sac(cfg), StopRule(cfg), np.random.default_rng(cfg.seed + 1)   # (rng: replay sampling)
    buf = policy.ReplayBuffer(cfg.buffer, obs_shapes(cfg))                                     # R
    run = rundir.Run(cfg, {"sac": sac, "curriculum": curr, "stop": stop, "env_rng": env.np_random, "sample_rng": rng},
                     buf, log, probe_update=cfg.updates * rundir.update_seconds(sac, zero_batch(buf, cfg)),
                     eval_episodes=len(cfg.levels) * -(-cfg.episodes // sac.helper.threads))   # (a worker: half)
    log(cli.format_config(cfg))
    log(f"parameters: {sac.parameter_counts()}; {cfg.device}" + (f", {sac.helper.threads} threads an update"
                                                                  if cfg.device == "cpu" else ""))
    with evaluate.second_core(sac.helper.threads, sac.device) as worker:    # validation and evaluation on 2 cores
        try:
            # Lines 7-12, learn the residual TA-MRP
            for ep in range(run.episode, cfg.train_episodes):               # line 8: for n in max-episodes
                if stop.stopped:                              # (resumed after it stopped as learned: evaluate it)
                    break
                env.set_ranges(*curr.ranges())                               # E_r and Ex_r where line 11 left them
                # line 9, interact with the environment, and store in R. The warm-up acts uniformly at random
                # (Spinning Up's start steps), so that the critics see every action before the actor follows them
                episode = rollout(env, sac.act if ep >= cfg.warmup else random_action)
                buf.add_episode(episode)
                run.lap("env")
                # line 10, update the policy with SAC
                losses = []
                for _ in range(cfg.updates if ep >= cfg.warmup else 0):
                    losses.append(sac.update(buf.sample(cfg.batch, rng, cfg.augment)))
                run.lap("update")
                curr.update(bool(episode["term"][-1]))                      # line 11: generate the curriculum, Eq. 16
                learned = stop.learned(env.e_r >= curr.final - 1e-9, lambda: validate(cfg, sac, curr, worker),
                                       lambda n: validate_families(cfg, sac, curr, worker, n), log, ep)
                run.save(episode, losses, sac.helper.threads, sr15=curr.success_rate, e_r_mm=env.e_r * 1000,
                         ex_r_mm=env.ex_r * 1000, delta=curr.delta)         # a kill loses at most the episode in flight
                if learned:
                    break
            return finish(cfg, sac, curr, run.seconds(), log, worker, stop.history)
        except KeyboardInterrupt:
            raise KeyboardInterrupt(f"every finished episode is saved; continue with --resume {cfg.run_dir}")
        finally:
            env.close()
            run.close()                                                      # (the run dir's lock with it)


def rollout(env, act, seed=None):
    """Algorithm 1, line 9: one episode with the residual act(obs) -> a, as the replay buffer takes it: T + 1
    observations, each with the privileged critics' 'state' (which the actor never reads), T actions, rewards,
    ends; and its return. seed: the episode's (None: the env's generator draws it, as in training)."""
    obs, info = env.reset(seed=seed)
    traj = {k: [v] for k, v in {**obs, "state": critic_state(info), "extra": critic_extra(info)}.items()}
    acts, rews, terms, done = [], [], [], False
    while not done:
        a = act(obs)
        obs, r, term, trunc, info = env.step(a)
        for k, v in {**obs, "state": critic_state(info), "extra": critic_extra(info)}.items():
            traj[k].append(v)
        acts.append(a)
        rews.append(r)
        terms.append(term)        # a trap: only a real end (success) stops the bootstrap, a time-out does not
        done = term or trunc
    return {"obs": {k: np.stack(v) for k, v in traj.items()}, "act": np.array(acts, np.float32),
            "rew": np.array(rews, np.float32), "term": np.array(terms, np.float32), "return": sum(rews)}


def random_action(obs):
    return (torch.rand(6) * 2 - 1).numpy()


def critic_state(info):
    """What privileged critics read besides the last readings, obs['state'] (STATE_DIM,): the tip's offset
    from the true goal X - X_g (x, y over 5 mm, z over 25 mm, yaw over 0.025 rad; m, rad), x and y again
    through tanh(. / 1 mm) so that the last millimetre, where the chamfer catches or misses, stands out,
    and the time as a fraction of the episode. Training knows X_g (Eq. 17's reward is made of it); the
    actor never reads this."""
    off, t = info["goal_offset"], info["t"] * sim.POLICY_HZ / sim.MAX_STEPS
    return np.array([off[0] / 0.005, off[1] / 0.005, off[2] / 0.025, off[3] / 0.025, np.tanh(off[0] / 0.001),
                     np.tanh(off[1] / 0.001), t], np.float32)


def critic_extra(info):
    """What multimodal critics (--critic multimodal) read besides the actor's observation, obs['extra'] (EXTRA_DIM,)
    (README difference 13): the time as a fraction of the episode and the curriculum's E_r and Ex_r over the final
    range, all of which the agent knows (the reward's W and the time left change with them)."""
    return np.array([info["t"] * sim.POLICY_HZ / sim.MAX_STEPS, info["e_r"] / sim.E_R_FINAL,
                     info["ex_r"] / sim.E_R_FINAL], np.float32)


def make_env(cfg, **kw):
    """The run's env: its task, context, view, clearance and largest range, with the hand-designed part (none for
    --vanilla) and, for keypoint RL, the keypoint in the observation."""
    return sim.AssemblyEnv(cfg.task, cfg.context, roi=cfg.roi, clearance=cfg.clearance_mm / 1000,
                           e_r_max=cfg.error_mm / 1000, base_policy=not cfg.vanilla, keypoint=cfg.obs == "ts-ptk",
                           randomize=cfg.families, tilt=cfg.tilt, **kw)


def make_sac(cfg, device=None):
    return policy.SAC(cfg.obs, POSE_SCALE, sim.F_MAX6, lr=cfg.lr, gamma=cfg.gamma, target_entropy=cfg.target_entropy,
                      state_dim=STATE_DIM if cfg.critic == "privileged" else 0,
                      extra_dim=EXTRA_DIM if cfg.critic == "multimodal" else 0, image_norm=cfg.image_norm,
                      threads=command.cores(cfg),
                      device=device or ("cpu" if cfg.device == "auto" else cfg.device))


def obs_shapes(cfg):
    """What the replay buffer keeps of an observation (what the critics read besides the actor's observation;
    keypoint RL's keypoint, not the image it was found in)."""
    return {**({"keypoint": (4,)} if cfg.obs == "ts-ptk" else {"image": (1, sim.IMG, sim.IMG)}),
            "pose_hist": (sim.HIST, 6), "wrench_hist": (sim.HIST, 6),
            **({"state": (STATE_DIM,)} if cfg.critic == "privileged" else {"extra": (EXTRA_DIM,)})}


def zero_batch(buf, cfg):
    """A batch of zeros shaped as buf.sample gives the run one (for the update-time probe)."""
    o = {k: np.zeros((cfg.batch, *v.shape[1:]), v.dtype) for k, v in buf.obs.items()}
    return o, np.zeros((cfg.batch, 6), np.float32), np.zeros(cfg.batch, np.float32), o, np.zeros(cfg.batch, np.float32)


class StopRule:
    """Stop when learned (the paper trains max-episodes: README difference 16): from `stop_held` episodes in a
    row at the final range on, every VAL_EVERY episodes the greedy policy tries VAL_EPISODES held-out
    episodes there; VAL_WINS wins end the run. (One pass: a second in a row, as issue 49 measured, made the
    quickstart's seeds train 10-30 episodes longer for no held-out success: docs/HISTORY.md.) A run that trains
    among families (--randomize) is validated every FAMILY_EVERY episodes, and where training's scene passes, in
    FAMILY_EPISODES scenes of each family's training side too; where each has FAMILY_WINS, in FAMILY_CONFIRM
    scenes of each (the same and more), and FAMILY_CONFIRM_WINS in each end it. (10 alone stopped a gear at
    episode 360 whose mixed held-out scenes it inserted in far fewer: docs/robust.md.) `history` keeps every
    validation (eval.json's, the episodes each seed took to hold)."""

    def __init__(self, cfg):
        self.stop_held, self.final_mm, self.episodes, self.held = cfg.stop_held, cfg.error_mm, cfg.train_episodes, 0
        self.families = cfg.families
        self.stopped = False                         # passed: what is left is the evaluation (kept in ckpt.pt)
        self.history = []                            # [{'episode': n, 'train': wins, family: wins, ...}]

    def learned(self, at_final, validate, validate_families, log, ep):
        self.held = self.held + 1 if at_final else 0                  # episodes in a row at the final range
        every = FAMILY_EVERY if self.families else VAL_EVERY
        if not (self.stop_held and self.held >= self.stop_held and (self.held - self.stop_held) % every == 0):
            return False
        wins = {"episode": ep + 1, "train": validate()}
        log(f"validation at episode {ep + 1}: the greedy policy inserted {wins['train']} of {VAL_EPISODES} at "
            f"{self.final_mm:g} mm")
        if wins["train"] >= VAL_WINS and self.families:
            wins.update(validate_families(FAMILY_EPISODES))
            log(f"  in {FAMILY_EPISODES} scenes of each family's training side: "
                + ", ".join(f"{f} {wins[f]}" for f in self.families))
            if all(wins[f] >= FAMILY_WINS for f in self.families):      # a first look that passed: confirmed on more
                wins["confirm"] = validate_families(FAMILY_CONFIRM)
                log(f"  in {FAMILY_CONFIRM} scenes of each: "
                    + ", ".join(f"{f} {wins['confirm'][f]}" for f in self.families))
        self.history.append(wins)
        self.stopped = self.holds(wins, self.families)
        if self.stopped:
            log(f"stopped as learned at episode {ep + 1} (--stop-held 0 trains all {self.episodes})")
        return self.stopped

    @staticmethod
    def holds(wins, families):
        """Whether a validation ({'train': wins, family: wins, ..., 'confirm': {family: wins}}) ends the run:
        training's scene, and each family's confirmation."""
        return wins["train"] >= VAL_WINS and all(wins.get("confirm", {}).get(f, -1) >= FAMILY_CONFIRM_WINS
                                                 for f in families)

    def state_dict(self):
        return {"held": self.held, "stopped": self.stopped, "history": self.history}

    def load_state_dict(self, d):                # (a checkpoint of before issue 49's change also holds 'passes')
        self.held, self.stopped, self.history = int(d["held"]), bool(d.get("stopped", False)), d.get("history", [])
        if self.stopped and self.history and not self.holds(self.history[-1], self.families):
            self.stopped = False                 # stopped by an earlier rule that this one does not confirm: trains on


def validate(cfg, sac, curr, worker=None, family=None, episodes=None):
    """Greedy successes at the final range in training's scene (VAL_EPISODES), or in `episodes` scenes of a
    randomized family's training side (FAMILY:train, never its held-out seeds; any n begin with the same scenes),
    in a new env, on seeds apart from training's and evaluation's (half of them played by worker, an
    evaluate.Worker, where there is one)."""
    pi = evaluate.TrainedPolicy(evaluate.policy_file(sac, {"obs": cfg.obs}), sac.device)   # sac.act's greedy action
    episodes = episodes or (FAMILY_EPISODES if family else VAL_EPISODES)
    with make_env(replace(cfg, context=f"{family}:train" if family else cfg.context, randomize=""), e_r=curr.final,
                  ex_r=curr.ranges()[1]) as env:
        row = evaluate.evaluate(env, pi, episodes, VAL_SEED + cfg.seed, log=lambda *_: None, worker=worker)
    return round(row["success_rate"] * episodes)


def validate_families(cfg, sac, curr, worker=None, episodes=None):
    """{family: validate's successes in `episodes` scenes of its training side} for each randomized family."""
    return {family: validate(cfg, sac, curr, worker, family, episodes) for family in cfg.families}


def policy_meta(cfg, curr):
    """What evaluation must know of training (policy.pt's meta): the task, encoder and view, the base policy, Ex_r
    where the curriculum stands, the largest E_r the view was made for (Eq. 11) and the tilt's room."""
    return {"task": cfg.task, "obs": cfg.obs, "roi": cfg.roi, "vanilla": cfg.vanilla, "ex_r": float(curr.ranges()[1]),
            "e_r_max": max(sim.E_R_FINAL, cfg.error_mm / 1000), "tilt": cfg.tilt}


def checkpoint_policy(path, ckpt):
    """A run's ckpt.pt (its contents, `ckpt`) -> the policy file its actor makes now (evaluate.policy_file), with
    the run's config.json beside it: the policy of a run that is unfinished or was interrupted. ValueError where
    the config cannot be read."""
    cfg = read_config(os.path.dirname(os.path.abspath(path)))
    sac, curr = make_sac(cfg, "cpu"), curriculum.Curriculum(cfg.curriculum, final=cfg.error_mm / 1000)
    sac.load_state_dict(ckpt["sac"])
    curr.load_state_dict(ckpt["curriculum"])
    return evaluate.policy_file(sac, policy_meta(cfg, curr))


def load_policy(path, device="cpu"):
    """A policy.pt, or a run's ckpt.pt, as an evaluate.TrainedPolicy: act(obs) -> action, one observation or a
    batch. ValueError saying what is wrong with a file that is neither."""
    return evaluate.load_policy(path, device, from_checkpoint=checkpoint_policy)


def finish(cfg, sac, curr, seconds, log, worker=None, stop_history=()):
    """policy.pt (with what evaluation must know of training), curves.png and eval.json: held-out seeds, and the
    stop rule's validations."""
    policy_path = os.path.join(cfg.run_dir, "policy.pt")
    evaluate.save_policy(policy_path, sac, policy_meta(cfg, curr))
    rundir.plot_curves(cfg.run_dir, f"{cfg.task}, {cfg.obs}, {cfg.curriculum}")
    pi = evaluate.load_policy(policy_path, sac.device)
    with evaluate.eval_env(cfg.task, pi, cfg.context, cfg.roi, cfg.clearance_mm, gui=cfg.gui) as env:
        show = lambda row: log(evaluate.format_row(f"TA-MRP {cfg.task} {row['error_mm']:g}mm", row))   # noqa: E731
        rows = evaluate.evaluate_levels(env, pi, cfg.levels, cfg.episodes, evaluate.EVAL_SEED + cfg.seed, log=show,
                                        worker=worker, progress=log)
    trained = len(rundir.read_metrics(cfg.run_dir)["episode"])     # fewer than --train-episodes if stopped as learned
    result = {"task": cfg.task, "obs": cfg.obs, "curriculum": cfg.curriculum, "context": cfg.context, "roi": cfg.roi,
              "seed": cfg.seed, "eval_seed": evaluate.EVAL_SEED + cfg.seed, "train_episodes": trained,
              "world": sim.WORLD, "train_minutes": round(seconds / 60, 1), "rows": rows,
              "validation": list(stop_history)}
    rundir.write_json(os.path.join(cfg.run_dir, "eval.json"), result)     # whole or not at all: the run's end
    log(f"wrote {cfg.run_dir}/policy.pt, metrics.csv, curves.png, eval.json")
    return result


# ---------------------------------------------------------------- the command line (command.py)
def parse_args(argv):
    """argv -> a checked Config (command.parse_args: a flag that would not apply is a mistake)."""
    return command.parse_args(Config, argv, "\n\n".join(__doc__.split("\n\n")[:2]))    # what it is, the commands


def read_config(run_dir):
    """A run's config.json as a Config; OSError, or ValueError if a value is not of its flag's type and choices."""
    return command.read_config(Config, run_dir)


def main(argv=None):
    def run(cfg):
        try:
            return command.run_evaluation(cfg, load_policy) if cfg.eval else train(cfg)
        except rundir.Busy as e:                   # a second writer
            raise ArgError(f"--{'resume' if cfg.resume else 'run-dir'} {cfg.run_dir!r}: {e}")
        except rundir.RunError as e:               # a run dir that cannot be continued as it is
            raise ArgError(f"--resume {cfg.run_dir!r}: {e}")
        except OSError as e:                       # a full disk, a file system gone read-only: the last checkpoint
            if e.errno not in cli.WRITE_ERRORS:    # is whole (rundir.replace_atomic)
                raise
            raise cli.Unwritable(f"cannot write {e.filename or cfg.run_dir or 'a file'} ({e.strerror})"
                                 + (f"; every finished episode is saved: free space, then --resume {cfg.run_dir}"
                                    if cfg.run_dir and not cfg.eval else ""))
    return cli.command("tacrl", lambda: run(parse_args(sys.argv[1:] if argv is None else list(argv))))


if __name__ == "__main__":
    sys.exit(main())
