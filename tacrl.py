"""tacrl.py: command line of tacrl, the companion code of Wang et al., "Task attention-based multimodal
fusion and curriculum residual learning for context generalization in robotic assembly" (2024).

Training (Algorithm 1): the hybrid policy of Sec. 4.1 with the residual TA-MRP (policy.py) learnt
by SAC, the error range growing with the adaptive curriculum of Eq. 16 (curriculum.py):

    python tacrl.py --task peg                         # train, then evaluate at 5/10/15/20 mm
    python tacrl.py --resume runs/peg-ts-ptv-adaptive-s0
    python tacrl.py --task peg --eval runs/peg-ts-ptv-adaptive-s0/policy.pt --error-mm 20 --episodes 20

Evaluation of the hand-designed policy alone (F_d = 0):

    python tacrl.py --task peg --eval initial --error-mm 0 --episodes 20
    python tacrl.py --task gear --eval initial --error-mm 20 --episodes 20 --json gear20.json
    python tacrl.py --task peg --eval initial --context loc-1 --video peg.mp4

A run directory holds config.json, ckpt.pt (networks, optimisers, curriculum, RNG states; every
episode), replay/ (one .npz per episode: the replay buffer), metrics.csv, and at the end policy.pt,
curves.png and eval.json.
"""
import argparse
import csv
import json
import os
import sys
import time
from dataclasses import asdict, dataclass, fields

import numpy as np

import sim


@dataclass
class Args:
    task: str = "peg"            # 'peg' (0.1 mm clearance) or 'gear' (Sec. 5.1.1)
    eval: str = ""               # evaluate instead of training: 'initial' (F_d = 0) or a policy.pt
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
    batch: int = 64              # SAC batch size
    buffer: int = 50000          # replay capacity, transitions
    lr: float = 3e-4             # Adam step size of actor, critics and temperature
    gamma: float = 0.95          # discount (0.99 let the critics thrash: see README)
    device: str = "auto"         # auto, cpu or cuda
    threads: int = 0             # torch CPU threads (0: torch's default, one per core)
    eval_levels: str = "5,10,15,20"  # error ranges (mm) of the evaluation after training (Table 2)
    run_dir: str = ""            # where the run lives; default runs/<task>-<obs>-<curriculum>-s<seed>
    resume: str = ""             # continue the run in this directory


HELP = {
    "task": "peg or gear", "eval": "'initial' (the hand-designed policy alone) or a policy.pt to evaluate; "
    "without it, train", "error_mm": "error range E_r in mm (0..30): evaluated, or the curriculum's final range",
    "episodes": "number of evaluation episodes",
    "context": f"one of {', '.join(sim.CONTEXTS)}", "roi": f"task or one of {', '.join(sim.ROI_PRESETS)}",
    "clearance_mm": "diametral clearance of the peg / gear bore, mm", "seed": "random seed",
    "json": "write the evaluation row to this JSON file", "video": "record the first evaluation episode to this .mp4",
    "gui": "open the PyBullet GUI", "train_episodes": "training episodes",
    "obs": "observations: pt, ts-pt or ts-ptv", "curriculum": "adaptive, none, g2-c30, g2-c10 or g2-c2",
    "updates": "gradient steps after each episode",
    "warmup": "episodes of uniform random actions before the first update", "threads": "torch CPU threads, 0 = all cores",
    "batch": "SAC batch size", "buffer": "replay capacity (transitions)", "lr": "learning rate",
    "gamma": "discount factor", "device": "auto, cpu or cuda", "run_dir": "run directory",
    "eval_levels": "comma-separated error ranges (mm) evaluated after training",
    "resume": "run directory to continue (its config.json wins over other flags)",
}


class ArgError(Exception):
    pass


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
    if a.eval and a.eval != "initial" and not os.path.isfile(a.eval):
        raise ArgError(f"--eval must be 'initial' or an existing policy.pt file, not {a.eval!r}")
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
    if not a.run_dir:
        a.run_dir = os.path.join("runs", f"{a.task}-{a.obs}-{a.curriculum}-s{a.seed}")


def load_config(run_dir):
    path = os.path.join(run_dir, "config.json")
    try:
        with open(path) as f:
            d = json.load(f)
        a = Args(**d)
    except FileNotFoundError:
        raise ArgError(f"--resume {run_dir!r}: no config.json there (not a run directory)")
    except (ValueError, TypeError) as e:
        raise ArgError(f"--resume {run_dir!r}: config.json is unreadable ({e})")
    a.run_dir, a.resume, a.eval = run_dir, run_dir, ""
    return a


def mean_std(x):
    """[mean, std], or None where there is nothing to average (no successful episode): JSON null."""
    x = np.asarray(x, float)
    return [float(x.mean()), float(x.std())] if len(x) else None


def evaluate(env, act, episodes, seed, video=None, log=print):
    """Roll out `act(obs) -> action` for `episodes` episodes; returns the Table-1/2-style row:
    success rate, completion time of the successful episodes (s), peak |contact force| per world
    axis in each episode (N) and cumulative reward, each as [mean, std]."""
    succ, times, forces, returns = [], [], [], []
    t0 = time.time()
    for ep in range(episodes):
        obs, info = env.reset(seed=seed * 100003 + ep)
        ret, peak, done = 0.0, np.zeros(3), False
        while not done:
            obs, r, term, trunc, info = env.step(act(obs))
            ret += r
            peak = np.maximum(peak, np.abs(info["f_world"][:3]))
            done = term or trunc
            if video is not None and ep == 0:
                video.write(env.world.render_external()[:, :, ::-1])
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


def format_row(name, row):
    ms = lambda k, f="{:.2f}": "-" if row[k] is None else f"{f.format(row[k][0])} +- {f.format(row[k][1])}"
    return (f"{'policy':<22} {'SR':>5}  {'CT (s)':>14}  {'Fx (N)':>14}  {'Fy (N)':>14}  {'Fz (N)':>14}  {'CR':>16}\n"
            f"{name:<22} {row['success_rate']:5.2f}  {ms('completion_time_s'):>14}  {ms('contact_force_x_N'):>14}  "
            f"{ms('contact_force_y_N'):>14}  {ms('contact_force_z_N'):>14}  {ms('cumulative_reward', '{:.1f}'):>16}")


# ---------------------------------------------------------------- policies and checkpoints
POSE_SCALE = [sim.E_R_FINAL] * 3 + [sim.E_ROT_FINAL] * 3    # the encoder divides the pose history by these
EVAL_SEED = 1000                                               # eval seeds: EVAL_SEED + --seed, never a training seed


def pick_device(name):
    import torch
    return ("cuda" if torch.cuda.is_available() else "cpu") if name == "auto" else name


def make_sac(a, device):
    import policy
    return policy.SAC(a.obs, POSE_SCALE, sim.F_MAX6, lr=a.lr, gamma=a.gamma, device=device)


def save_atomic(obj, path):
    """torch.save to path.tmp, then rename: an interrupt leaves the old file or the new one."""
    import torch
    torch.save(obj, path + ".tmp")
    os.replace(path + ".tmp", path)


def save_policy(path, sac, a):
    """What evaluation needs: the encoder and the actor (the critics stay in ckpt.pt)."""
    d = {"format": "tacrl-policy-1", "task": a.task, "obs": a.obs, "roi": a.roi,
         "enc": sac.enc.state_dict(), "actor": sac.actor.state_dict()}
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
    return lambda obs: policy.act(enc, actor, obs, deterministic=True, device=device)


# ---------------------------------------------------------------- training (Algorithm 1)
METRICS = ["episode", "return", "success", "sr15", "e_r_mm", "ex_r_mm", "delta", "steps", "total_steps",
           "updates", "q_loss", "pi_loss", "alpha", "entropy", "env_s", "update_s", "elapsed_s"]


def rng_state(rng):
    return json.dumps(rng.bit_generator.state)


def set_rng_state(rng, s):
    rng.bit_generator.state = json.loads(s)


def save_episode(path, ep):
    """One episode as ReplayBuffer.add_episode takes it, as plain arrays (np.load needs no pickle)."""
    np.savez(path + ".tmp.npz", act=ep["act"], rew=ep["rew"], term=ep["term"],
             **{"obs_" + k: v for k, v in ep["obs"].items()})
    os.replace(path + ".tmp.npz", path)


def load_episode(path):
    with np.load(path, allow_pickle=False) as z:
        return {"obs": {k[4:]: z[k] for k in z.files if k.startswith("obs_")},
                "act": z["act"], "rew": z["rew"], "term": z["term"]}


def episode_files(run_dir):
    d = os.path.join(run_dir, "replay")
    return sorted((int(f[3:9]), os.path.join(d, f)) for f in os.listdir(d) if f.startswith("ep_") and
                  f.endswith(".npz") and ".tmp" not in f)


def trim_episode_files(run_dir, capacity, keep_upto):
    """Delete replay files past the checkpoint (an episode cut short by an interrupt) and the oldest
    ones that the ring buffer no longer holds; returns the rest as paths, oldest first."""
    kept, n_kept = [], 0
    for n, f in reversed(episode_files(run_dir)):
        if n > keep_upto or n_kept >= capacity:
            os.remove(f)
            continue
        with np.load(f, allow_pickle=False) as z:
            n_kept += len(z["act"])
        kept.append(f)
    return kept[::-1]


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
    env = sim.AssemblyEnv(a.task, a.context, roi=a.roi, clearance=a.clearance_mm / 1000, gui=a.gui)
    env.rng = np.random.default_rng(a.seed)
    sample_rng = np.random.default_rng(a.seed + 1)
    shapes = {"image": (sim.IMG, sim.IMG), "pose_hist": (sim.HIST, 6), "wrench_hist": (sim.HIST, 6)}
    buf = policy.ReplayBuffer(a.buffer, shapes)
    start, total_steps, elapsed0 = 0, 0, 0.0
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
        for f in trim_episode_files(a.run_dir, a.buffer, start):
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
            traj = {k: [v] for k, v in obs.items()}
            acts, rews, terms, done, ret = [], [], [], False, 0.0
            while not done:
                # warm-up: uniform actions (Spinning Up's start steps), so that the critics have
                # seen the whole action range before the actor starts to follow their gradient
                act = (torch.rand(6) * 2 - 1).numpy() if ep < a.warmup else sac.act(obs)
                obs, r, term, trunc, info = env.step(act)
                for k, v in obs.items():
                    traj[k].append(v)
                acts.append(act)
                rews.append(r)
                terms.append(term)        # only a real end stops the bootstrap; a time-out does not
                ret += r
                done = term or trunc
            episode = {"obs": {k: np.stack(v) for k, v in traj.items()}, "act": np.array(acts, np.float32),
                       "rew": np.array(rews, np.float32), "term": np.array(terms, np.float32)}
            save_episode(os.path.join(replay_dir, f"ep_{ep + 1:06d}.npz"), episode)
            buf.add_episode(episode)
            total_steps += len(acts)
            if total_steps > a.buffer:     # keep on disk only what the ring buffer holds
                trim_episode_files(a.run_dir, a.buffer, ep + 1)
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
                    for k in ("q_loss", "pi_loss", "alpha", "entropy")}
            row = {"episode": ep + 1, "return": round(ret, 3), "success": int(success), "sr15": round(curr.success_rate, 3),
                   "e_r_mm": round(e_r * 1000, 3), "ex_r_mm": round(max(ex_r, sim.EX_MIN) * 1000, 3),
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
        save_policy(os.path.join(a.run_dir, "policy.pt"), sac, a)
        plot_curves(metrics_path, os.path.join(a.run_dir, "curves.png"), f"{a.task}, {a.obs}, {a.curriculum}")
        # -- Table-2-style evaluation with a seed never used in training
        act = load_policy(os.path.join(a.run_dir, "policy.pt"), a.task, device)
        result = {"task": a.task, "obs": a.obs, "curriculum": a.curriculum, "context": a.context, "roi": a.roi,
                  "seed": a.seed, "eval_seed": EVAL_SEED + a.seed, "train_episodes": a.train_episodes,
                  "train_minutes": round((time.time() - t_start) / 60, 1), "rows": []}
        levels = sorted({float(x) for x in a.eval_levels.split(",")})
        for mm in levels:
            env.set_ranges(mm / 1000)
            row = evaluate(env, act, a.episodes, EVAL_SEED + a.seed, log=lambda *_: None)
            row["error_mm"] = mm
            result["rows"].append(row)
            log(format_row(f"TA-MRP {a.task} {mm:g}mm", row))
    finally:
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


# ---------------------------------------------------------------- the command line
def main(argv=None):
    try:
        a = parse_args(argv)
        if not a.eval:
            print("config:", asdict(a))
            train(a)
            return 0
        act = (lambda obs: np.zeros(6)) if a.eval == "initial" else load_policy(a.eval, a.task, pick_device(a.device))
    except ArgError as e:
        print(f"tacrl: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        where = f"; continue with --resume {a.run_dir}" if "a" in locals() and not a.eval else ""
        print(f"\ninterrupted: every finished episode is saved{where}", file=sys.stderr)
        return 130
    print("config:", asdict(a))
    env = sim.AssemblyEnv(a.task, a.context, e_r=a.error_mm / 1000, roi=a.roi, clearance=a.clearance_mm / 1000,
                          gui=a.gui)
    video = None
    if a.video:
        import cv2
        frame = env.world.render_external()
        video = cv2.VideoWriter(a.video, cv2.VideoWriter_fourcc(*"mp4v"), sim.POLICY_HZ, frame.shape[1::-1])
    name = "initial" if a.eval == "initial" else "TA-MRP"
    try:
        row = evaluate(env, act, a.episodes, a.seed, video)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        if video is not None:
            video.release()
        env.close()
    row.update({"task": a.task, "policy": a.eval, "error_mm": a.error_mm, "context": a.context, "roi": a.roi,
                "seed": a.seed})
    print(format_row(f"{name} {a.task} {a.error_mm:g}mm", row))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(row, f, indent=2)
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
