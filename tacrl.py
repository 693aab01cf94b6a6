"""tacrl.py: Algorithm 1 of Wang et al., "Task attention-based multimodal fusion and curriculum residual
learning for context generalization in robotic assembly" (Applied Intelligence, 2024), and the
evaluation of its Tables 1-2. The residual TA-MRP (policy.py) learns F_d on top of the hybrid policy
(control.py, sim.py) while the adaptive curriculum of Eq. 16 (curriculum.py) widens the error range:

    python tacrl.py --task peg                            # train, then evaluate at 5/10/15/20 mm
    python tacrl.py --resume runs/peg-ts-ptv-adaptive-s0  # continue after Ctrl-C or a crash
    python tacrl.py --task peg --eval runs/peg-ts-ptv-adaptive-s0/policy.pt --error-mm 20
    python tacrl.py --task peg --eval initial --error-mm 0      # the hand-designed policy alone
    python tacrl.py --task peg --eval two-step --error-mm 20    # the classical baseline (baselines.py)

A run directory holds config.json, ckpt.pt (networks, optimisers, curriculum, RNG states; after every
episode), replay/ (the replay buffer, one .npz an episode), metrics.csv, and at the end policy.pt,
curves.png and eval.json. Several seeds in parallel: seeds.py; the results report: report.py.
"""
import argparse
import csv
import json
import os
import sys
import time
from dataclasses import asdict, dataclass, field, fields

import cv2
import numpy as np
import torch

import baselines
import curriculum
import figures
import legacy
import policy
import sim


def opt(default, help, choices=None):
    """A Config field with its --help text and allowed values: each flag is described here only."""
    return field(default=default, metadata={"help": help, "choices": choices})


@dataclass
class Config:
    # what to run
    task: str = opt("peg", "peg (16 mm peg, 0.1 mm clearance) or gear (Sec. 5.1.1)", ("peg", "gear"))
    eval: str = opt("", "evaluate, not train: initial (F_d = 0), two-step (baselines.py) or a policy.pt")
    resume: str = opt("", "continue the run in this directory (its config.json wins over other flags)")
    seed: int = opt(0, "seeds the errors, the networks and the replay sampling")
    # the task (Sec. 5.1.1)
    error_mm: float = opt(20.0, "error range E_r in mm (Eq. 13-15), 0..30: evaluated, or the curriculum's final one")
    context: str = opt("train", "board location and background (Sec. 5.1.4)", tuple(sim.CONTEXTS))
    roi: str = opt("task", "image window: task (Eq. 11's task attention) or a window of Fig. 11",
                   ("task", *sim.ROI_PRESETS))
    clearance_mm: float = opt(0.1, "diametral clearance of the peg or the gear's bore, mm")
    # Algorithm 1
    train_episodes: int = opt(300, "max-episodes of Algorithm 1")
    obs: str = opt("ts-ptv", "observations (Fig. 9); v, image only: the visual baseline", policy.OBS_KINDS)
    curriculum: str = opt("adaptive", "error curriculum (Eq. 16, Fig. 10); ex10: E_r adaptive, Ex_r held at 10 mm "
                                      "(Fig. 9)", curriculum.KINDS)
    vanilla: bool = opt(False, "the vanilla baseline: no trajectory guidance, the residual acts alone")
    critic: str = opt("privileged", "privileged critics also read X - X_g (README difference 13)",
                      ("privileged", "multimodal"))
    updates: int = opt(200, "SAC gradient steps after each episode (Sec. 5.1.1: 200)")
    warmup: int = opt(20, "episodes of uniform random actions before the first update (the authors' loop: 20)")
    batch: int = opt(64, "SAC batch size")
    buffer: int = opt(50000, "replay capacity, transitions")
    lr: float = opt(3e-4, "Adam step size of actor, critics and temperature")
    gamma: float = opt(0.95, "discount (0.99 let the critics thrash: README difference 10)")
    target_entropy: float = opt(-6.0, "SAC's entropy target (the usual -|A|)")
    # evaluation (Tables 1-2)
    episodes: int = opt(20, "evaluation episodes a level (the paper: 20 test trials)")
    eval_levels: str = opt("5,10,15,20", "error ranges (mm) evaluated after training (Table 2)")
    json: str = opt("", "also write the evaluation row to this JSON file")
    video: str = opt("", "record the first evaluation episode from an external camera to this .mp4")
    # the machine
    run_dir: str = opt("", "run directory (default: runs/<task>-<obs>-<curriculum>[-e<mm>][-roi-<roi>]...-s<seed>)")
    device: str = opt("auto", "where torch runs", ("auto", "cpu", "cuda"))
    threads: int = opt(0, "torch CPU threads (0: torch's default, one a core)")
    gui: bool = opt(False, "open the PyBullet window")


EVAL_SEED = 1000             # evaluation episodes use seeds from EVAL_SEED + seed: never a training seed
POSE_SCALE = np.array([sim.E_R_FINAL] * 3 + [sim.E_ROT_FINAL] * 3)   # m, rad: the encoders' pose units
STATE_DIM = 7                # the privileged critics' obs['state'] (critic_state)
BASELINES = ("initial", "two-step")
METRICS = ["episode", "return", "success", "sr15", "e_r_mm", "ex_r_mm", "delta", "steps", "total_steps", "updates",
           "q_loss", "pi_loss", "alpha", "entropy", "env_s", "update_s", "elapsed_s"]


# ---------------------------------------------------------------- the command line
class ArgError(Exception):
    """A user's mistake: reported as one line, exit code 2."""


class Parser(argparse.ArgumentParser):
    """argparse, but a mistake is an ArgError (one line, exit code 2, no usage dump) and no flag may be
    abbreviated (a typo of one flag must not pass as another)."""

    def __init__(self, **kw):
        super().__init__(allow_abbrev=False, **kw)

    def error(self, message):
        raise ArgError(message)


def parse_args(argv):
    ap = Parser(description=__doc__.split("\n\n")[0])
    for f in fields(Config):
        flag, hlp = "--" + f.name.replace("_", "-"), f.metadata["help"]
        if f.type is bool:
            ap.add_argument(flag, action="store_true", help=hlp)
        else:
            ap.add_argument(flag, type=f.type, default=f.default, choices=f.metadata["choices"],
                            help=f"{hlp} (default: {f.default})" if f.default != "" else hlp)
    cfg = Config(**vars(ap.parse_args(argv)))
    if cfg.resume:
        cfg = load_config(cfg.resume)
    check(cfg)
    return cfg


def check(cfg):
    """Every flag's value, before any work starts."""
    for f in fields(Config):                        # argparse checks these too, but not a resumed config.json's
        if f.metadata["choices"] and getattr(cfg, f.name) not in f.metadata["choices"]:
            raise ArgError(f"--{f.name} must be one of {', '.join(f.metadata['choices'])}, not {getattr(cfg, f.name)!r}")
    for name, least in {"episodes": 1, "train_episodes": 1, "batch": 1, "buffer": 1, "updates": 0, "warmup": 0,
                        "threads": 0}.items():
        if getattr(cfg, name) < least:
            raise ArgError(f"--{name.replace('_', '-')} must be at least {least}, not {getattr(cfg, name)}")
    try:
        levels = [float(x) for x in cfg.eval_levels.split(",")]
    except ValueError:
        levels = []
    for bad, msg in [
            (cfg.eval and cfg.eval not in BASELINES and not os.path.isfile(cfg.eval),
             f"--eval must be {', '.join(BASELINES)} or an existing policy.pt file, not {cfg.eval!r}"),
            (cfg.eval == "two-step" and cfg.task != "peg", "--eval two-step is the peg-in-hole baseline (Table 1)"),
            (not 0.0 <= cfg.error_mm <= 30.0, f"--error-mm must be within 0..30, not {cfg.error_mm}"),
            (not 0.0 < cfg.lr < 1.0, f"--lr must be within (0, 1), not {cfg.lr}"),
            (not 0.0 < cfg.gamma < 1.0, f"--gamma must be within (0, 1), not {cfg.gamma}"),
            (not 0.0 < cfg.clearance_mm <= 2.0, f"--clearance-mm must be within (0, 2], not {cfg.clearance_mm}"),
            (cfg.video and not cfg.video.endswith(".mp4"), f"--video must name an .mp4 file, not {cfg.video!r}"),
            (not levels or not all(0.0 <= x <= 30.0 for x in levels),
             f"--eval-levels must be comma-separated error ranges in 0..30 mm, not {cfg.eval_levels!r}"),
            (cfg.device == "cuda" and not torch.cuda.is_available(), "--device cuda: no CUDA device is available")]:
        if bad:
            raise ArgError(msg)
    if not cfg.run_dir:
        cfg.run_dir = default_run_dir(cfg)


def default_run_dir(cfg):
    """runs/<task>-[vanilla-]<obs>-<curriculum>[-e<E_r mm>][-roi-<roi>][-<critic>]-s<seed>: the flags of
    the baselines and ablations are in its name, so that no run overwrites another's directory."""
    name = f"{cfg.task}-{'vanilla-' if cfg.vanilla else ''}{cfg.obs}-{cfg.curriculum}"
    name += f"-e{cfg.error_mm:g}" if cfg.error_mm != Config.error_mm else ""
    name += f"-roi-{cfg.roi}" if cfg.roi != "task" else ""
    name += f"-{cfg.critic}" if cfg.critic != Config.critic else ""
    return os.path.join("runs", f"{name}-s{cfg.seed}")


# ---------------------------------------------------------------- configs, checkpoints, small helpers
def read_config(run_dir):
    """A run's config.json as a dict."""
    with open(os.path.join(run_dir, "config.json")) as f:
        return legacy.upgrade_config(json.load(f))


def load_config(run_dir):
    try:
        cfg = Config(**read_config(run_dir))
    except FileNotFoundError:
        raise ArgError(f"--resume {run_dir!r}: no config.json there (not a run directory)")
    except (ValueError, TypeError, AttributeError) as e:      # AttributeError: not a JSON object
        raise ArgError(f"--resume {run_dir!r}: config.json is unreadable ({e})")
    cfg.run_dir, cfg.resume, cfg.eval = run_dir, run_dir, ""
    return cfg


def pick_device(name):
    return ("cuda" if torch.cuda.is_available() else "cpu") if name == "auto" else name


def critic_state(info):
    """What the privileged critics read besides the last readings (STATE_DIM,): X - X_g (x, y over 5
    mm, z over 25 mm, yaw over 0.025 rad), x and y again through tanh(. / 1 mm) so that the last
    millimetre, where the chamfer catches or misses, stands out, and the time over the episode's 24 s.
    Training knows X_g (Eq. 17's reward is made of it); the actor never sees this."""
    off = info["goal_offset"]
    return np.array([off[0] / 0.005, off[1] / 0.005, off[2] / 0.025, off[3] / 0.025, np.tanh(off[0] / 0.001),
                     np.tanh(off[1] / 0.001), info["t"] * sim.POLICY_HZ / sim.MAX_STEPS], np.float32)


def make_sac(cfg, device):
    return policy.SAC(cfg.obs, POSE_SCALE, sim.F_MAX6, lr=cfg.lr, gamma=cfg.gamma, target_entropy=cfg.target_entropy,
                      state_dim=STATE_DIM if cfg.critic == "privileged" else 0, device=device)


def parameter_counts(sac):
    n = lambda *ms: sum(p.numel() for m in ms for p in m.parameters())   # noqa: E731
    shared = ", shared with the critics" if sac.shared else ""
    return (f"actor {n(sac.actor_enc, sac.actor):,} (encoder {n(sac.actor_enc):,}{shared}), "
            f"critics {n(sac.enc, sac.q):,} (encoder {n(sac.enc):,}, twin Q {n(sac.q):,})")


def fmt_time(s):
    s = int(s)
    return f"{s // 3600}h{s // 60 % 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


def save_checkpoint(path, episode, total_steps, elapsed, sac, curr, env, sample_rng):
    policy.save_atomic({"episode": episode, "total_steps": total_steps, "elapsed": elapsed, "sac": sac.state_dict(),
                 "curriculum": json.dumps(curr.state_dict()), "env_rng": json.dumps(env.np_random.bit_generator.state),
                 "sample_rng": json.dumps(sample_rng.bit_generator.state), "torch_rng": torch.get_rng_state()}, path)


def load_checkpoint(path, device, sac, curr, env, sample_rng):
    """Restore a checkpoint into the run's objects; returns (episode, total_steps, elapsed s)."""
    try:
        ck = torch.load(path, map_location=device, weights_only=True)
        sac.load_state_dict(ck["sac"])
        curr.load_state_dict(json.loads(ck["curriculum"]))
        env.np_random.bit_generator.state = json.loads(ck["env_rng"])
        sample_rng.bit_generator.state = json.loads(ck["sample_rng"])
        torch.set_rng_state(ck["torch_rng"])
        return int(ck["episode"]), int(ck["total_steps"]), float(ck["elapsed"])
    except Exception as e:
        raise ArgError(f"--resume {os.path.dirname(path)!r}: ckpt.pt is corrupt or does not match this run's "
                       f"config ({type(e).__name__}: {str(e).splitlines()[0][:120]})")


# ---------------------------------------------------------------- training (Algorithm 1)
def rollout(env, act):
    """Algorithm 1, line 9: one episode of the hybrid policy with the residual act(obs) -> a. Returns
    (episode, return): the episode as the replay buffer takes it, T + 1 observations (with 'state',
    the privileged critics' input, which the actor never reads), T actions, rewards and 'terminated'."""
    obs, info = env.reset()
    traj = {k: [v] for k, v in {**obs, "state": critic_state(info)}.items()}
    acts, rews, terms, ret, done = [], [], [], 0.0, False
    while not done:
        a = act(obs)
        obs, r, term, trunc, info = env.step(a)
        for k, v in {**obs, "state": critic_state(info)}.items():
            traj[k].append(v)
        acts.append(a)
        rews.append(r)
        ret += r
        terms.append(term)        # a trap: only a real end (success) stops the bootstrap, a time-out does not
        done = term or trunc
    return {"obs": {k: np.stack(v) for k, v in traj.items()}, "act": np.array(acts, np.float32),
            "rew": np.array(rews, np.float32), "term": np.array(terms, np.float32)}, ret


def start_run(cfg, device, sac, curr, env, sample_rng, buf, log):
    """A new run dir, or the one --resume continues; returns (episode, total_steps, elapsed s) to go on from."""
    ckpt, metrics = os.path.join(cfg.run_dir, "ckpt.pt"), os.path.join(cfg.run_dir, "metrics.csv")
    if not (cfg.resume and os.path.exists(ckpt)):
        buf.restore(0)                               # no episode is saved: clear a replay/ left before one was
        with open(os.path.join(cfg.run_dir, "config.json"), "w") as f:
            json.dump({k: v for k, v in asdict(cfg).items() if k != "resume"}, f, indent=2)
        with open(metrics, "w", newline="") as f:
            csv.DictWriter(f, METRICS).writeheader()
        return 0, 0, 0.0
    start, total_steps, elapsed = load_checkpoint(ckpt, device, sac, curr, env, sample_rng)
    buf.restore(start)
    with open(metrics) as f:                         # drop the rows of an episode the checkpoint has not got
        rows = [r for r in csv.DictReader(f) if int(r["episode"]) <= start]
    with open(metrics, "w", newline="") as f:
        csv.DictWriter(f, METRICS).writeheader()
        csv.DictWriter(f, METRICS).writerows(rows)
    log(f"resumed {cfg.run_dir} at episode {start} ({len(buf)} transitions in the replay buffer)")
    return start, total_steps, elapsed


def record(cfg, ep, ret, episode, env, curr, losses, total_steps, times):
    """Append the episode's row to metrics.csv; returns its progress line. times (s): env, update, elapsed, ETA."""
    mean = {k: round(float(np.mean([x[k] for x in losses])), 5) if losses else float("nan")
            for k in ("q_loss", "pi_loss", "alpha", "entropy")}
    row = {"episode": ep + 1, "return": round(ret, 3), "success": int(episode["term"][-1]),
           "sr15": round(curr.success_rate, 3), "e_r_mm": round(env.e_r * 1000, 3), "ex_r_mm": round(env.ex_r * 1000, 3),
           "delta": round(curr.delta, 4), "steps": len(episode["act"]), "total_steps": total_steps,
           "updates": len(losses), **mean, "env_s": round(times[0], 2), "update_s": round(times[1], 2),
           "elapsed_s": round(times[2], 1)}
    with open(os.path.join(cfg.run_dir, "metrics.csv"), "a", newline="") as f:
        csv.DictWriter(f, METRICS).writerow(row)
    return (f"ep {ep + 1:4d}/{cfg.train_episodes}  R {ret:7.1f}  succ {row['success']}  sr15 {curr.success_rate:4.2f}  "
            f"E_r {row['e_r_mm']:4.1f}mm  Ex_r {row['ex_r_mm']:4.1f}mm  delta {curr.delta:5.3f}  steps {row['steps']:3d}  "
            f"env {times[0]:4.1f}s  upd {times[1]:4.1f}s  elapsed {fmt_time(times[2])}  ETA {fmt_time(times[3])}")


def train(cfg, log=lambda msg: print(msg, flush=True)):
    """Algorithm 1: learning context-generalized TA-MRP with ACRRL. Returns eval.json's contents."""
    ckpt_path = os.path.join(cfg.run_dir, "ckpt.pt")
    if not cfg.resume and os.path.exists(ckpt_path):
        raise ArgError(f"{cfg.run_dir!r} already holds a run: continue it with --resume {cfg.run_dir} "
                       f"or pick another --run-dir")
    device = pick_device(cfg.device)
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    # Lines 1-5, initialize the learning architecture: the env holds the hand-designed part of the
    # skill (2: tau(t) and K, Eq. 8-9, 14), the error range E_r (3), the ROI for E_r (4: Eq. 11, at
    # the largest range) and the reward (5: Eq. 17-18)
    env = sim.AssemblyEnv(cfg.task, cfg.context, roi=cfg.roi, clearance=cfg.clearance_mm / 1000, gui=cfg.gui,
                          trajectory=not cfg.vanilla, e_r_max=cfg.error_mm / 1000)
    env.np_random = np.random.default_rng(cfg.seed)
    # line 6: the curriculum's parameters for E_r (Eq. 16)
    curr = curriculum.Curriculum(cfg.curriculum, final=cfg.error_mm / 1000)
    sac = make_sac(cfg, device)
    shapes = {"image": (sim.IMG, sim.IMG), "pose_hist": (sim.HIST, 6), "wrench_hist": (sim.HIST, 6),
              **({"state": (STATE_DIM,)} if cfg.critic == "privileged" else {})}     # what the buffer keeps
    buf = policy.ReplayBuffer(cfg.buffer, shapes, directory=os.path.join(cfg.run_dir, "replay"))
    sample_rng = np.random.default_rng(cfg.seed + 1)
    try:
        start, total_steps, elapsed0 = start_run(cfg, device, sac, curr, env, sample_rng, buf, log)
        log(f"config: {asdict(cfg)}")
        log(f"parameters: {parameter_counts(sac)}; {device}, {torch.get_num_threads()} torch threads")
        t_start = time.time() - elapsed0
        # Lines 7-12, learn the residual TA-MRP
        for ep in range(start, cfg.train_episodes):                     # line 8: for n in max-episodes
            t0 = time.time()
            env.set_ranges(*curr.ranges())
            # line 9, interact with the environment. The warm-up acts uniformly at random (Spinning
            # Up's start steps), so that the critics see every action before the actor follows them
            act = (lambda obs: (torch.rand(6) * 2 - 1).numpy()) if ep < cfg.warmup else sac.act
            episode, ret = rollout(env, act)
            buf.add_episode(episode, number=ep + 1)
            total_steps += len(episode["act"])
            t_env, t0 = time.time() - t0, time.time()
            losses = [sac.update(buf.sample(cfg.batch, sample_rng))     # line 10: update the policy with SAC
                      for _ in range(cfg.updates if ep >= cfg.warmup else 0)]
            t_upd = time.time() - t0
            curr.update(bool(episode["term"][-1]))                     # line 11: generate the curriculum, Eq. 16
            elapsed = time.time() - t_start
            eta = (elapsed - elapsed0) / (ep + 1 - start) * (cfg.train_episodes - ep - 1)
            line = record(cfg, ep, ret, episode, env, curr, losses, total_steps, (t_env, t_upd, elapsed, eta))
            save_checkpoint(ckpt_path, ep + 1, total_steps, elapsed, sac, curr, env, sample_rng)   # then it is done
            log(line)
    except KeyboardInterrupt:
        raise KeyboardInterrupt(f"every finished episode is saved; continue with --resume {cfg.run_dir}")
    finally:
        env.close()
    return finish(cfg, sac, curr, env.e_r_max, device, time.time() - t_start, log)


def finish(cfg, sac, curr, e_r_max, device, seconds, log):
    """After the last episode: policy.pt, curves.png, and eval.json, the Table-2-style evaluation on
    seeds never used in training, in a new simulator."""
    # what evaluation needs to know of training: the view and the guidance it learned with, the exploration
    # range Ex_r (m) it ended with (the stiffness of Eq. 9 it learned to push) and the env's e_r_max
    # (m: its ROI and X_i)
    policy_path = os.path.join(cfg.run_dir, "policy.pt")
    policy.save_policy(policy_path, sac, {"task": cfg.task, "obs": cfg.obs, "roi": cfg.roi, "vanilla": cfg.vanilla,
                                          "ex_r": float(curr.ranges()[1]), "e_r_max": float(e_r_max)})
    figures.plot_curves(os.path.join(cfg.run_dir, "metrics.csv"), os.path.join(cfg.run_dir, "curves.png"),
                        f"{cfg.task}, {cfg.obs}, {cfg.curriculum}")
    pi = load_policy(policy_path, cfg.task, device)
    levels = sorted({float(x) for x in cfg.eval_levels.split(",")})
    with eval_env(cfg.task, pi, cfg.context, cfg.roi, cfg.clearance_mm, gui=cfg.gui) as env:
        rows = evaluate_levels(env, pi, levels, cfg.episodes, EVAL_SEED + cfg.seed,
                               log=lambda row: log(format_row(f"TA-MRP {cfg.task} {row['error_mm']:g}mm", row)))
    result = {"task": cfg.task, "obs": cfg.obs, "curriculum": cfg.curriculum, "context": cfg.context, "roi": cfg.roi,
              "seed": cfg.seed, "eval_seed": EVAL_SEED + cfg.seed, "train_episodes": cfg.train_episodes,
              "train_minutes": round(seconds / 60, 1), "rows": rows}
    with open(os.path.join(cfg.run_dir, "eval.json"), "w") as f:
        json.dump(result, f, indent=2)
    log(f"wrote {cfg.run_dir}/policy.pt, metrics.csv, curves.png, eval.json")
    return result


# ---------------------------------------------------------------- evaluation (Tables 1-2)
def load_policy(path, task, device="cpu"):
    """policy.pt -> policy.TrainedPolicy; a file that is not one, or one for another task, is a user error."""
    try:
        pi = policy.TrainedPolicy(legacy.upgrade_policy(torch.load(path, map_location=device, weights_only=True)), device)
    except Exception as e:          # corrupt, truncated, foreign: one line for the user
        raise ArgError(f"--eval {path!r}: cannot load the policy ({type(e).__name__}: {str(e).splitlines()[0][:120]})")
    if pi.meta["task"] != task:
        raise ArgError(f"--eval {path!r}: this policy was trained for --task {pi.meta['task']}, not {task}")
    return pi


def eval_env(task, act, context="train", roi="task", clearance_mm=0.1, e_r_mm=0.0, gui=False):
    """A new simulator for evaluating `act` (for a TrainedPolicy: at the Ex_r, the ROI and X_i it was
    trained for, with its guidance). Always a new one: PyBullet carries state across resets (bullet3
    issue 2442; measured here too), so the simulator a run trained in would give other numbers."""
    m = act.meta if isinstance(act, policy.TrainedPolicy) else {}
    return sim.AssemblyEnv(task, context, e_r=e_r_mm / 1000, ex_r=m.get("ex_r"), roi=roi, clearance=clearance_mm / 1000,
                           gui=gui, trajectory=not m.get("vanilla", False), e_r_max=m.get("e_r_max"))


def mean_std(x):
    """[mean, std], or None where there is nothing to average (no successful episode): JSON null."""
    x = np.asarray(x, float)
    return [float(x.mean()), float(x.std())] if len(x) else None


def evaluate(env, act, episodes, seed, video=None, log=print):
    """Roll out act(obs) -> action for `episodes` episodes (episode k's seed: seed * 100003 + k); returns the
    Table-1/2 row: success rate, completion time of the successful episodes (s), peak |contact force|
    per world axis in each episode (N) and cumulative reward, each as [mean, std]."""
    succ, times, forces, returns = [], [], [], []
    t0 = time.time()
    for ep in range(episodes):
        peak = np.zeros(3)

        def on_step(obs, r, info, first=ep == 0):
            np.maximum(peak, np.abs(info["f_world"][:3]), out=peak)
            if video is not None and first:
                video.write(env.world.render_external()[:, :, ::-1])     # RGB -> OpenCV's BGR
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
    policy's training ended (the controller stays as trained)."""
    rows = []
    for mm in levels:
        env.set_ranges(mm / 1000, act.meta["ex_r"])
        row = evaluate(env, act, episodes, seed, log=lambda *_: None)
        row.update(error_mm=mm, ex_r_mm=round(env.ex_r * 1000, 3))
        rows.append(row)
        log(row)
    return rows


def format_row(name, row):
    ms = lambda k, f="{:.2f}": "-" if row[k] is None else f"{f.format(row[k][0])} +- {f.format(row[k][1])}"  # noqa: E731
    return (f"{'policy':<22} {'SR':>5}  {'CT (s)':>14}  {'Fx (N)':>14}  {'Fy (N)':>14}  {'Fz (N)':>14}  {'CR':>16}\n"
            f"{name:<22} {row['success_rate']:5.2f}  {ms('completion_time_s'):>14}  {ms('contact_force_x_N'):>14}  "
            f"{ms('contact_force_y_N'):>14}  {ms('contact_force_z_N'):>14}  {ms('cumulative_reward', '{:.1f}'):>16}")


def run_evaluation(cfg):
    """--eval: a policy.pt, the hand-designed policy alone or the two-step baseline, at --error-mm."""
    pi = None if cfg.eval in BASELINES else load_policy(cfg.eval, cfg.task, pick_device(cfg.device))
    if pi is not None and pi.meta["roi"] != cfg.roi:      # its encoder learned that view, not another
        raise ArgError(f"--eval {cfg.eval!r}: this policy was trained with --roi {pi.meta['roi']}, not {cfg.roi}")
    print(f"config: {asdict(cfg)}", flush=True)
    with eval_env(cfg.task, pi, cfg.context, cfg.roi, cfg.clearance_mm, cfg.error_mm, cfg.gui) as env:
        act = pi
        if cfg.eval == "initial":
            act = lambda obs: np.zeros(6)          # noqa: E731  the hand-designed policy alone, F_d = 0
        elif cfg.eval == "two-step":
            act = baselines.TwoStep(env)
            print(f"two-step: calibrated the image -> offset map, median error {act.calibrate() * 1000:.2f} mm")
        video = None
        if cfg.video:
            frame = env.world.render_external()
            video = cv2.VideoWriter(cfg.video, cv2.VideoWriter_fourcc(*"mp4v"), sim.POLICY_HZ, frame.shape[1::-1])
        try:
            row = evaluate(env, act, cfg.episodes, EVAL_SEED + cfg.seed, video)   # the seeds of eval.json
        finally:
            if video is not None:
                video.release()
        row.update({"task": cfg.task, "policy": cfg.eval, "error_mm": cfg.error_mm, "ex_r_mm": round(env.ex_r * 1000, 3),
                    "context": cfg.context, "roi": cfg.roi, "seed": cfg.seed})
    print(format_row(f"{cfg.eval if pi is None else 'TA-MRP'} {cfg.task} {cfg.error_mm:g}mm", row))
    if cfg.json:
        with open(cfg.json, "w") as f:
            json.dump(row, f, indent=2)
        print(f"wrote {cfg.json}")


def command(prog, fn):
    """Run fn() as a command: a user's mistake (ArgError) is one line and exit code 2, Ctrl-C one line
    and exit code 130. report.py and seeds.py run the same way."""
    try:
        fn()
        return 0
    except ArgError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as e:
        print(f"\n{prog}: interrupted" + (f": {e}" if str(e) else ""), file=sys.stderr)
        return 130


def main(argv=None):
    def run(cfg):
        return run_evaluation(cfg) if cfg.eval else train(cfg)
    return command("tacrl", lambda: run(parse_args(sys.argv[1:] if argv is None else list(argv))))


if __name__ == "__main__":
    sys.exit(main())
