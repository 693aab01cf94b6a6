"""tacrl.py: Algorithm 1 of Wang et al., "Task attention-based multimodal fusion and curriculum residual
learning for context generalization in robotic assembly" (Applied Intelligence, 2024), and the
evaluation of its Tables 1-2. The residual TA-MRP (policy.py) learns F_d on top of the hybrid policy
(control.py, sim.py) while the adaptive curriculum of Eq. 16 (curriculum.py) widens the error range:

    python tacrl.py --task peg                            # train, then evaluate at 5/10/15/20 mm
    python tacrl.py --resume runs/peg-ts-ptv-adaptive-s0  # continue (with --train-episodes N: extend)
    python tacrl.py --task peg --eval runs/peg-ts-ptv-adaptive-s0/policy.pt --error-mm 20
    python tacrl.py --task peg --eval initial --error-mm 0      # the hand-designed policy alone
    python tacrl.py --task peg --eval two-step --error-mm 20    # the classical baseline (baselines.py)

A run dir holds config.json, ckpt.pt (networks, optimisers, curriculum, RNG states: after every episode),
replay/ (one .npz an episode), metrics.csv, then policy.pt, curves.png, eval.json. Several seeds: seeds.py.
"""
import csv
import importlib
import json
import os
import signal
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, fields, replace

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130, not a traceback
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\ntacrl: interrupted\n"), os._exit(130)))

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

import baselines  # noqa: E402
import curriculum  # noqa: E402
import figures  # noqa: E402
import legacy  # noqa: E402
import policy  # noqa: E402
import sim  # noqa: E402
import cli  # noqa: E402
from cli import ArgError, opt  # noqa: E402


def train_opt(*args, **kw):                       # a flag for training only (refused with --eval)
    return opt(*args, mode="train", **kw)


@dataclass
class Config:
    # what to run
    task: str = opt("peg", "peg (16 mm peg, 0.1 mm clearance) or gear (Sec. 5.1.1)", ("peg", "gear"))
    eval: str = opt("", "evaluate, not train: initial (F_d = 0), two-step (baselines.py) or a policy.pt")
    resume: str = train_opt("", "continue the run in this directory as its config.json says")
    seed: int = opt(0, "seeds the errors, the networks and the replay sampling", bounds=(0, 2 ** 31 - 1))
    # the task (Sec. 5.1.1)
    error_mm: float = opt(20.0, "error range E_r in mm (Eq. 13-15): evaluated, or the curriculum's final one",
                          bounds=(0.0, 30.0))
    context: str = opt("train", "board location and background (Sec. 5.1.4)", tuple(sim.CONTEXTS))
    roi: str = opt("task", "image window: task (Eq. 11's task attention) or a window of Fig. 11",
                   ("task", *sim.ROI_PRESETS))
    clearance_mm: float = opt(0.1, "diametral clearance of the peg or the gear's bore, mm", bounds=(0.0, 2.0),
                              open_bounds=True)
    # Algorithm 1 (training only)
    train_episodes: int = train_opt(300, "max-episodes of Algorithm 1: the most a run trains", bounds=(1, None))
    stop_held: int = train_opt(30, "stop when learned: after this many episodes at the final range, every 10 the greedy "
                                   "policy tries 20 there; 19 wins twice in a row stop the run (0: never)", bounds=(0, None))
    obs: str = train_opt("ts-ptv", "observations (Fig. 9); v: the visual baseline", policy.OBS_KINDS)
    curriculum: str = train_opt("adaptive", "error curriculum (Eq. 16, Fig. 10); ex10: Fig. 9's", curriculum.KINDS)
    vanilla: bool = train_opt(False, "the vanilla baseline: no trajectory guidance, the residual acts alone")
    critic: str = train_opt("privileged", "privileged: also X - X_g (README difference 13)", ("privileged", "multimodal"))
    augment: float = train_opt(0.0, "image jitter s: brightness, contrast x U(1-s, 1+s) (README difference 17)", bounds=(0, 1))
    updates: int = train_opt(200, "SAC gradient steps after each episode (Sec. 5.1.1: 200)", bounds=(0, None))
    warmup: int = train_opt(20, "random-action episodes before the first update (the authors' loop: 20)", bounds=(0, None))
    batch: int = train_opt(64, "SAC batch size", bounds=(1, None))
    buffer: int = train_opt(50000, "replay capacity, transitions (at least an episode and a batch)", bounds=(1, None))
    lr: float = train_opt(3e-4, "Adam step size of actor, critics and temperature", bounds=(0, 1), open_bounds=True)
    gamma: float = train_opt(0.95, "discount (0.99 let the critics thrash: README difference 10)", bounds=(0, 1), open_bounds=True)
    target_entropy: float = train_opt(-6.0, "SAC's entropy target (the usual -|A|)")
    eval_levels: str = train_opt("5,10,15,20", "error ranges (mm) evaluated after training (Table 2)")
    run_dir: str = train_opt("", "run directory, new or empty (default: runs/<task>-<obs>-...-s<seed>)")
    # evaluation (Tables 1-2)
    episodes: int = opt(20, "evaluation episodes a level (the paper: 20 test trials)", bounds=(1, None))
    json: str = opt("", "also write the evaluation row to this new JSON file", mode="eval")
    video: str = opt("", "record the first evaluation episode from an external camera to this new .webm (VP9) or "
                         ".mp4 (H.264, where OpenCV has it): a browser plays either", mode="eval")
    track: bool = train_opt(False, "also log to TensorBoard in <run dir>/tb: metrics.csv's columns, the losses, now and "
                                   "then the task-attention image (pip install -e '.[track]'; tensorboard --logdir runs)")
    # the machine
    device: str = opt("auto", "where torch runs", ("auto", "cpu", "cuda"))
    threads: int = opt(0, "torch CPU threads (0: one a core that other processes leave free, measured as the run goes: "
                          "torch's one a core slowed updates 3-4x beside one busy program)", bounds=(0, None))
    gui: bool = opt(False, "open the PyBullet window")


EVAL_SEED = 1000             # evaluation episodes use seeds from EVAL_SEED + seed: never a training seed
POSE_SCALE = np.array([sim.E_R_FINAL] * 3 + [sim.E_ROT_FINAL] * 3)   # m, rad: the encoders' pose units
BASELINES = baselines.NAMES
RESUME_MAY_SET = ("resume", "train_episodes", "stop_held", "threads", "track")   # to extend a run; nothing else changes
VAL_SEED, VAL_EPISODES, VAL_WINS, VAL_EVERY, VAL_PASSES = 2000, 20, 19, 10, 2   # stop when learned: 19 of 20 twice
METRICS = ["episode", "return", "success", "sr15", "e_r_mm", "ex_r_mm", "delta", "steps", "total_steps", "updates",
           "q_loss", "pi_loss", "alpha", "entropy", "env_s", "update_s", "elapsed_s"]


# ---------------------------------------------------------------- the command line
def parse_args(argv):
    """argv -> a checked Config. A flag that would not apply (a training flag with --eval, or the other way
    round; with --resume, all but those of RESUME_MAY_SET) is a mistake, not silently ignored."""
    given = cli.parse(Config, argv, __doc__.split("\n\n")[0])      # only the flags on the command line
    mode = "eval" if "eval" in given else "train"
    for f in fields(Config):
        if f.name in given and f.metadata["mode"] not in (None, mode):
            raise ArgError(f"--{f.name.replace('_', '-')} is for {'--eval' if mode == 'train' else 'training'}: it "
                           f"would have no effect {'when training' if mode == 'train' else 'with --eval'}")
    if "resume" in given:
        others = [f"--{k.replace('_', '-')}" for k in given if k not in RESUME_MAY_SET]
        if others:
            raise ArgError(f"--resume continues a run as its config.json says: {', '.join(others)} cannot change "
                           f"it (--train-episodes N extends it)")
        run_dir = given.pop("resume")
        cfg = replace(load_config(run_dir), **given)
        if os.path.exists(os.path.join(run_dir, "eval.json")) and not set(given) - {"threads", "track"}:
            raise ArgError(f"--resume {run_dir!r}: the run is finished; extend it with --train-episodes N (and "
                           f"--stop-held 0 to train past the point where it stopped as learned)")
    else:
        cfg = Config(**given)
    check(cfg)
    return cfg


def check(cfg):
    """Every value, and every file the command will write, before any work starts."""
    cli.check_bounds(cfg)
    try:
        levels = [float(x) for x in cfg.eval_levels.split(",")]
    except ValueError:
        levels = []
    e_r_max = max(cfg.error_mm, sim.E_R_FINAL * 1000)      # the training env's largest range (ROI, X_i), mm
    for bad, msg in [
            (cfg.eval and cfg.eval not in BASELINES and not os.path.isfile(cfg.eval),
             f"--eval must be {', '.join(BASELINES)} or an existing policy.pt file, not {cfg.eval!r}"),
            (cfg.eval == "two-step" and cfg.task != "peg", "--eval two-step is the peg-in-hole baseline (Table 1)"),
            (cfg.buffer < max(cfg.batch, sim.MAX_STEPS), f"--buffer {cfg.buffer} must hold an episode ({sim.MAX_STEPS} "
                                                         f"transitions) and a batch (--batch {cfg.batch})"),
            (cfg.video and video_ext(cfg.video) not in VIDEO_FOURCC,
             f"--video must name a .webm (VP9) or .mp4 (H.264) file, not {cfg.video!r}"),
            (not levels or not all(0.0 <= x <= e_r_max for x in levels),
             f"--eval-levels must be comma-separated error ranges in 0..{e_r_max:g} mm (the run's env covers "
             f"--error-mm, and at least 20), not {cfg.eval_levels!r}"),
            (cfg.device == "cuda" and not torch.cuda.is_available(), "--device cuda: no CUDA device is available"),
            (cfg.gui and sim.display_problem(), f"--gui: {sim.display_problem()}")]:
        if bad:
            raise ArgError(msg)
    if cfg.track:
        try:
            importlib.import_module("torch.utils.tensorboard")
        except ImportError:
            raise ArgError("--track logs to TensorBoard, which is not installed: pip install -e '.[track]'")
    cli.warn_oversubscribed("tacrl", cfg.threads)
    for name in [x for x in ("json", "video") if getattr(cfg, x)]:   # written after the work: checked before it
        cli.check_new_file(getattr(cfg, name), f"--{name}")
    if cfg.video:                                   # the codec, tried on a scratch file: a format this OpenCV
        with tempfile.TemporaryDirectory() as tmp:  # cannot write is a mistake before any work, not after it
            open_video(os.path.join(tmp, "probe" + video_ext(cfg.video)), (64, 48), name=cfg.video).release()
    if cfg.device == "auto":                        # cuda where there is one
        cfg.device = "cuda" if torch.cuda.is_available() else "cpu"
    if not cfg.eval:
        cfg.run_dir = cfg.run_dir or default_run_dir(cfg)
        cli.check_dir_writable(cfg.run_dir, "--run-dir")
        left = os.listdir(cfg.run_dir) if os.path.isdir(cfg.run_dir) else []
        if not cfg.resume and "config.json" in left:
            raise ArgError(f"{cfg.run_dir!r} already holds a run: continue it with --resume {cfg.run_dir} "
                           f"or pick another --run-dir")
        if not cfg.resume and set(left) - {cli.LOG}:
            raise ArgError(f"--run-dir {cfg.run_dir!r} is not empty: a new run starts in a new or empty directory")


VIDEO_FOURCC = {".webm": "VP90", ".mp4": "avc1"}   # VP9 and H.264: what browsers play (MDN's web video codec guide)


def video_ext(path):
    return os.path.splitext(path)[1].lower()


def open_video(path, size, fps=sim.POLICY_HZ, name=None):
    """A cv2.VideoWriter of (w, h) BGR frames, its codec chosen by the extension; ArgError where this OpenCV
    cannot write that format (OpenCV's pip wheels encode VP9 with libvpx but carry no H.264 encoder)."""
    ext = video_ext(path)
    with sim.quiet_c_output():                     # FFmpeg's notices (a codec tag it does not know for WebM)
        writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*VIDEO_FOURCC[ext]), fps, size)
    if not writer.isOpened():
        codec = {".mp4": "H.264", ".webm": "VP9"}[ext]
        hint = "; name a .webm file instead (VP9, which every current browser plays)" if ext == ".mp4" else ""
        raise ArgError(f"--video {name or path!r}: this OpenCV ({cv2.__version__}) has no {codec} encoder{hint}")
    return writer


def default_run_dir(cfg):
    """runs/<task>-[vanilla-]<obs>-<curriculum>[-e<E_r mm>][-roi-<roi>][-<critic>][-aug<s>]-s<seed>: the flags of
    the baselines and ablations are in its name, so that no run overwrites another's directory."""
    name = f"{cfg.task}-{'vanilla-' if cfg.vanilla else ''}{cfg.obs}-{cfg.curriculum}"
    name += f"-e{cfg.error_mm:g}" if cfg.error_mm != Config.error_mm else ""
    name += f"-roi-{cfg.roi}" if cfg.roi != "task" else ""
    name += f"-{cfg.critic}" if cfg.critic != Config.critic else ""
    name += f"-aug{cfg.augment:g}" if cfg.augment else ""
    return os.path.join("runs", f"{name}-s{cfg.seed}")


# ---------------------------------------------------------------- configs, checkpoints, small helpers
def read_config(run_dir):
    """A run's config.json as a Config; ValueError if a value is not of its flag's type and choices."""
    with open(os.path.join(run_dir, "config.json")) as f:
        return cli.from_dict(Config, legacy.upgrade_config(json.load(f)))


def load_config(run_dir):
    try:
        cfg = read_config(run_dir)
    except NotADirectoryError:
        raise ArgError(f"--resume {run_dir!r} is a file, not a run directory")
    except FileNotFoundError:
        raise ArgError(f"--resume {run_dir!r}: no config.json there (not a run directory)")
    except (OSError, ValueError) as e:              # a directory named config.json, bad JSON, a wrong type
        raise ArgError(f"--resume {run_dir!r}: config.json is unreadable ({cli.describe(e)})")
    cfg.run_dir, cfg.resume, cfg.eval = run_dir, run_dir, ""
    return cfg


def make_sac(cfg, device):
    return policy.SAC(cfg.obs, POSE_SCALE, sim.F_MAX6, lr=cfg.lr, gamma=cfg.gamma, target_entropy=cfg.target_entropy,
                      state_dim=policy.STATE_DIM if cfg.critic == "privileged" else 0, device=device)


def save_checkpoint(path, episode, total_steps, elapsed, stop, sac, curr, env, sample_rng, buf):
    policy.save_atomic({"episode": episode, "total_steps": total_steps, "elapsed": elapsed, "stop": list(stop),
                        "sac": sac.state_dict(),
                        "curriculum": json.dumps(curr.state_dict()), "replay": json.dumps(buf.state_dict()),
                        "env_rng": json.dumps(env.np_random.bit_generator.state),
                        "sample_rng": json.dumps(sample_rng.bit_generator.state), "torch_rng": torch.get_rng_state()},
                       path)


def load_checkpoint(path, device, sac, curr, env, sample_rng):
    """Restore a checkpoint into the run's objects: (episode, total_steps, elapsed s, (episodes at E_final,
    validations passed in a row), the replay's state)."""
    try:
        ck = policy.load_file(path, device)
        sac.load_state_dict(ck["sac"])
        curr.load_state_dict(json.loads(ck["curriculum"]))
        env.np_random.bit_generator.state = json.loads(ck["env_rng"])
        sample_rng.bit_generator.state = json.loads(ck["sample_rng"])
        torch.set_rng_state(ck["torch_rng"])
        return int(ck["episode"]), int(ck["total_steps"]), float(ck["elapsed"]), tuple(ck["stop"]), json.loads(ck["replay"])
    except Exception as e:
        raise ArgError(f"--resume {os.path.dirname(path)!r}: ckpt.pt is damaged or does not match this run's "
                       f"config ({cli.describe(e)})")


def eta_seconds(ep, cfg, env_s, update_s, probe_s):
    """Seconds the episodes after `ep` will take: the mean env time, plus after the warm-up an update phase."""
    left = cfg.train_episodes - ep - 1
    with_updates = left - max(0, min(left, cfg.warmup - ep - 1))
    return left * float(np.mean(env_s)) + with_updates * (float(np.mean(update_s)) if update_s else probe_s)


# ---------------------------------------------------------------- training (Algorithm 1)
def rollout(env, act):
    """Algorithm 1, line 9: one episode with the residual act(obs) -> a, as the replay buffer takes it (T + 1
    observations with the critics' 'state', which the actor never reads; T actions, rewards, ends), and its return."""
    obs, info = env.reset()
    state = lambda info: policy.critic_state(info["goal_offset"], info["t"] * sim.POLICY_HZ / sim.MAX_STEPS)  # noqa: E731
    traj = {k: [v] for k, v in {**obs, "state": state(info)}.items()}
    acts, rews, terms, ret, done = [], [], [], 0.0, False
    while not done:
        a = act(obs)
        obs, r, term, trunc, info = env.step(a)
        for k, v in {**obs, "state": state(info)}.items():
            traj[k].append(v)
        acts.append(a)
        rews.append(r)
        ret += r
        terms.append(term)        # a trap: only a real end (success) stops the bootstrap, a time-out does not
        done = term or trunc
    return {"obs": {k: np.stack(v) for k, v in traj.items()}, "act": np.array(acts, np.float32),
            "rew": np.array(rews, np.float32), "term": np.array(terms, np.float32)}, ret


def start_run(cfg, device, sac, curr, env, sample_rng, buf, log):
    """A new or resumed run dir, checked and restored: (episode, total_steps, elapsed s, stop-rule state)."""
    ckpt, metrics = os.path.join(cfg.run_dir, "ckpt.pt"), os.path.join(cfg.run_dir, "metrics.csv")
    start, total_steps, elapsed, stop, finished, replay = 0, 0, 0.0, (0, 0), False, {"i": 0, "n": 0, "files": []}
    if os.path.exists(ckpt):                         # else new, or stopped before its first episode was saved
        start, total_steps, elapsed, stop, replay = load_checkpoint(ckpt, device, sac, curr, env, sample_rng)
        finished = os.path.exists(os.path.join(cfg.run_dir, "eval.json"))
        if cfg.train_episodes < start:
            raise ArgError(f"--resume {cfg.run_dir!r}: the run has {start} episodes; --train-episodes "
                           f"{cfg.train_episodes} is fewer")
    try:                                             # what the checkpoint holds; what it has not got goes
        rows = cli.read_log(metrics, METRICS, start)
        buf.restore(replay)                          # (it checks its files before it deletes any)
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ArgError(f"--resume {cfg.run_dir!r}: cannot continue the run: {cli.describe(e)}")
    cli.write_log(metrics, METRICS, rows)
    stop = (stop[0], 0) if finished else stop         # extended: validate anew, and keep what it wrote
    if finished:                                      # its policy's files and cached evaluations: *-epN.*
        cli.set_aside(cfg.run_dir, start)
    if not start or finished:
        with open(os.path.join(cfg.run_dir, "config.json"), "w") as f:
            json.dump({k: v for k, v in asdict(cfg).items() if k != "resume"}, f, indent=2)
    if start:
        log(f"resumed {cfg.run_dir} at episode {start} of {cfg.train_episodes}: networks, optimisers, curriculum "
            f"(E_r {curr.ranges()[0] * 1000:g} mm), random states, metrics.csv and the replay buffer ({len(buf)} "
            f"transitions)" + (f"; the finished run's files are now *-ep{start}.*" if finished else ""))
    return start, total_steps, elapsed, stop


TB_GROUPS = {"charts": ("return", "success", "sr15", "e_r_mm", "ex_r_mm", "delta", "steps", "total_steps", "updates"),
             "losses": ("q_loss", "pi_loss", "alpha", "entropy"), "time": ("env_s", "update_s", "elapsed_s")}
TB_IMAGE_EVERY = 10          # episodes between the task-attention images sent to TensorBoard


def tensorboard_writer(cfg, start):
    """--track: a TensorBoard writer on <run dir>/tb, CleanRL's convention (charts/, losses/); resumed, it
    hides what an earlier process wrote past the checkpoint (purge_step). None without --track."""
    if not cfg.track:
        return None
    from torch.utils.tensorboard import SummaryWriter     # the `track` extra; check() made sure it loads
    return SummaryWriter(os.path.join(cfg.run_dir, "tb"), purge_step=start + 1 if start else None)


def record(cfg, ep, ret, episode, env, curr, losses, total_steps, times, tb=None):
    """Append the episode's row to metrics.csv (and to TensorBoard with --track); returns its progress line.
    times (s): env, update, elapsed, ETA."""
    mean = {k: round(float(np.mean([x[k] for x in losses])), 5) if losses else float("nan")
            for k in ("q_loss", "pi_loss", "alpha", "entropy")}
    row = {"episode": ep + 1, "return": round(ret, 3), "success": int(episode["term"][-1]),
           "sr15": round(curr.success_rate, 3), "e_r_mm": round(env.e_r * 1000, 3), "ex_r_mm": round(env.ex_r * 1000, 3),
           "delta": round(curr.delta, 4), "steps": len(episode["act"]), "total_steps": total_steps,
           "updates": len(losses), **mean, "env_s": round(times[0], 2), "update_s": round(times[1], 2),
           "elapsed_s": round(times[2], 1)}
    with open(os.path.join(cfg.run_dir, "metrics.csv"), "a", newline="") as f:
        csv.DictWriter(f, METRICS).writerow(row)
    if tb is not None:
        for group, keys in TB_GROUPS.items():
            for k in keys:
                if np.isfinite(row[k]):                   # no losses during the warm-up
                    tb.add_scalar(f"{group}/{k}", row[k], ep + 1)
        if ep % TB_IMAGE_EVERY == 0:                      # what the policy saw as the episode began, (80, 80) uint8
            tb.add_image("obs/task_attention", episode["obs"]["image"][0], ep + 1, dataformats="HW")
        tb.flush()
    return (f"ep {ep + 1:4d}/{cfg.train_episodes}  R {ret:7.1f}  succ {row['success']}  sr15 {curr.success_rate:4.2f}  "
            f"E_r {row['e_r_mm']:4.1f}mm  Ex_r {row['ex_r_mm']:4.1f}mm  delta {curr.delta:5.3f}  steps {row['steps']:3d}  "
            f"env {times[0]:4.1f}s  upd {times[1]:4.1f}s ({torch.get_num_threads()} thr)  elapsed {cli.fmt_time(times[2])}  "
            f"ETA {cli.fmt_time(times[3])}")


def train(cfg, log=lambda msg: print(msg, flush=True)):
    """Algorithm 1: learning context-generalized TA-MRP with ACRRL. Returns eval.json's contents."""
    # torch's threads: --threads, or one a core that other processes leave free. The trade: updates on 1 and on
    # 2 threads differ in the last digits (a LayerNorm's and a convolution's gradient sums are split by thread),
    # so a run repeats to the last digit only with --threads fixed
    share = cli.CoreShare(cfg.threads)
    torch.set_num_threads(share.free())
    torch.manual_seed(cfg.seed)
    # Lines 1-5, initialize the learning architecture: the env holds the hand-designed part of the skill (2: tau(t)
    # and K, Eq. 8-9, 14), the error range E_r (3), the ROI for E_r (4: Eq. 11, at the largest) and the reward (5)
    env = sim.AssemblyEnv(cfg.task, cfg.context, roi=cfg.roi, clearance=cfg.clearance_mm / 1000, gui=cfg.gui,
                          trajectory=not cfg.vanilla, e_r_max=cfg.error_mm / 1000)
    env.np_random = np.random.default_rng(cfg.seed)
    # line 6: the curriculum's parameters for E_r (Eq. 16)
    curr = curriculum.Curriculum(cfg.curriculum, final=cfg.error_mm / 1000)
    sac = make_sac(cfg, cfg.device)
    shapes = {"image": (sim.IMG, sim.IMG), "pose_hist": (sim.HIST, 6), "wrench_hist": (sim.HIST, 6),
              **({"state": (policy.STATE_DIM,)} if cfg.critic == "privileged" else {})}     # what the buffer keeps
    sample_rng = np.random.default_rng(cfg.seed + 1)
    tb = None
    try:
        os.makedirs(cfg.run_dir, exist_ok=True)
        buf = policy.ReplayBuffer(cfg.buffer, shapes, directory=os.path.join(cfg.run_dir, "replay"))
        start, total_steps, elapsed0, (held, passes) = start_run(cfg, cfg.device, sac, curr, env, sample_rng, buf, log)
        tb = tensorboard_writer(cfg, start)
        log(f"config: {asdict(cfg)}")
        log(f"parameters: {sac.parameter_counts()}; {cfg.device}, " + (f"{cfg.threads} torch threads" if cfg.threads else
            f"torch threads: one a core that other processes leave free ({torch.get_num_threads()} of {share.cores} now)"))
        probe_s, env_s, update_s = sac.update_seconds(shapes, cfg.batch) * cfg.updates, [], []
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
            env_s.append(time.time() - t0)
            t0 = time.time()
            losses = [sac.update(buf.sample(cfg.batch, sample_rng, cfg.augment))     # line 10: update the policy with SAC
                      for _ in share.steps(cfg.updates if ep >= cfg.warmup else 0, torch.set_num_threads)]
            update_s += [time.time() - t0] if losses else []
            curr.update(bool(episode["term"][-1]))                     # line 11: generate the curriculum, Eq. 16
            held = held + 1 if env.e_r >= curr.final - 1e-9 else 0     # episodes in a row at the final range
            if cfg.stop_held and held >= cfg.stop_held and (held - cfg.stop_held) % VAL_EVERY == 0:   # learned?
                wins = validate(cfg, sac, curr, env.e_r_max)
                passes = passes + 1 if wins >= VAL_WINS else 0
                if tb is not None:
                    tb.add_scalar("charts/validation_wins", wins, ep + 1)
                log(f"validation at episode {ep + 1}: the greedy policy inserted {wins} of {VAL_EPISODES} at "
                    f"{cfg.error_mm:g} mm ({passes} of {VAL_PASSES} passes in a row)")
            elapsed = time.time() - t_start
            times = (env_s[-1], time.time() - t0, elapsed, eta_seconds(ep, cfg, env_s, update_s, probe_s))
            line = record(cfg, ep, ret, episode, env, curr, losses, total_steps, times, tb)
            save_checkpoint(os.path.join(cfg.run_dir, "ckpt.pt"), ep + 1, total_steps, elapsed, (held, passes), sac,
                            curr, env, sample_rng, buf)
            buf.prune()                              # only now: the last checkpoint still needed those files
            log(line)
            if passes >= VAL_PASSES:
                log(f"stopped as learned at episode {ep + 1} (--stop-held 0 trains all {cfg.train_episodes})")
                break
    except KeyboardInterrupt:
        raise KeyboardInterrupt(f"every finished episode is saved; continue with --resume {cfg.run_dir}")
    finally:
        env.close()
        if tb is not None:
            tb.close()
    return finish(cfg, sac, curr, env.e_r_max, cfg.device, time.time() - t_start, log)


def validate(cfg, sac, curr, e_r_max):
    """Greedy successes at the final range, in a new env, on seeds apart from training's and evaluation's."""
    with sim.AssemblyEnv(cfg.task, cfg.context, e_r=curr.final, ex_r=curr.ranges()[1], roi=cfg.roi, e_r_max=e_r_max,
                         clearance=cfg.clearance_mm / 1000, trajectory=not cfg.vanilla) as env:
        row = evaluate(env, lambda obs: sac.act(obs, deterministic=True), VAL_EPISODES, VAL_SEED + cfg.seed,
                       log=lambda *_: None)
    return round(row["success_rate"] * VAL_EPISODES)


def finish(cfg, sac, curr, e_r_max, device, seconds, log):
    """policy.pt (with what evaluation must know of training), curves.png and eval.json: held-out seeds."""
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
    with open(os.path.join(cfg.run_dir, "metrics.csv")) as f:
        trained = sum(1 for _ in f) - 1               # fewer than --train-episodes when it stopped as learned
    result = {"task": cfg.task, "obs": cfg.obs, "curriculum": cfg.curriculum, "context": cfg.context, "roi": cfg.roi,
              "seed": cfg.seed, "eval_seed": EVAL_SEED + cfg.seed, "train_episodes": trained, "world": sim.WORLD,
              "train_minutes": round(seconds / 60, 1), "rows": rows}
    with open(os.path.join(cfg.run_dir, "eval.json"), "w") as f:
        json.dump(result, f, indent=2)
    log(f"wrote {cfg.run_dir}/policy.pt, metrics.csv, curves.png, eval.json")
    return result


# ---------------------------------------------------------------- evaluation (Tables 1-2)
def load_policy(path, task, device="cpu"):
    """policy.pt -> policy.TrainedPolicy; a file that is not one, or one for another task, is a user error."""
    try:
        pi = policy.TrainedPolicy(legacy.upgrade_policy(policy.load_file(path, device)), device)
        missing = {"task", "roi", "vanilla", "ex_r", "e_r_max"} - set(pi.meta)   # what training tells evaluation
        if missing:
            raise ValueError(f"its meta lacks {', '.join(sorted(missing))}")
    except Exception as e:          # corrupt, truncated, foreign: one line for the user
        raise ArgError(f"--eval {path!r}: cannot load the policy ({cli.describe(e)})")
    if pi.meta["task"] != task:
        raise ArgError(f"--eval {path!r}: this policy was trained for --task {pi.meta['task']}, not {task}")
    return pi


def eval_env(task, act, context="train", roi="task", clearance_mm=0.1, e_r_mm=0.0, gui=False):
    """The env to evaluate `act` in; a TrainedPolicy's at the Ex_r, ROI and X_i it was trained for, with its guidance."""
    m = act.meta if isinstance(act, policy.TrainedPolicy) else {}
    return sim.AssemblyEnv(task, context, e_r=e_r_mm / 1000, ex_r=m.get("ex_r"), roi=roi, clearance=clearance_mm / 1000,
                           gui=gui, trajectory=not m.get("vanilla", False), e_r_max=m.get("e_r_max"))


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
        log(f"episode {ep + 1}/{episodes}  success {int(term)}  time {info['t']:5.1f}s  return {ret:7.1f}  |F|max x/y/z "
            f"{peak[0]:5.1f}/{peak[1]:5.1f}/{peak[2]:5.1f} N  elapsed {el:5.0f}s  ETA {el / (ep + 1) * (episodes - ep - 1):4.0f}s")
    forces = np.array(forces)
    mean_std = lambda x: [float(np.mean(x)), float(np.std(x))] if len(x) else None   # noqa: E731 (None: no success)
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
    pi = None if cfg.eval in BASELINES else load_policy(cfg.eval, cfg.task, cfg.device)
    if pi is not None and pi.meta["roi"] != cfg.roi:      # its encoder learned that view, not another
        raise ArgError(f"--eval {cfg.eval!r}: this policy was trained with --roi {pi.meta['roi']}, not {cfg.roi}")
    if pi is not None and cfg.error_mm > pi.meta["e_r_max"] * 1000 + 1e-6:   # Eq. 11's ROI would widen
        raise ArgError(f"--error-mm {cfg.error_mm:g}: this policy's view covers {pi.meta['e_r_max'] * 1000:g} mm")
    print(f"config: {asdict(cfg)}", flush=True)
    with eval_env(cfg.task, pi, cfg.context, cfg.roi, cfg.clearance_mm, cfg.error_mm, cfg.gui) as env:
        video = None
        if cfg.video:
            video = open_video(cfg.video, env.world.render_external().shape[1::-1])
        act = pi if pi is not None else baselines.make(cfg.eval, env)
        if cfg.eval == "two-step":
            print(f"two-step: calibrated the image -> offset map, median error {act.fit_error * 1000:.2f} mm")
        try:
            row = evaluate(env, act, cfg.episodes, EVAL_SEED + cfg.seed, video)   # the seeds of eval.json
        finally:
            if video is not None:
                with sim.quiet_c_output():
                    video.release()
        row.update({"task": cfg.task, "policy": cfg.eval, "error_mm": cfg.error_mm, "ex_r_mm": round(env.ex_r * 1000, 3),
                    "context": cfg.context, "roi": cfg.roi, "seed": cfg.seed})
    print(format_row(f"{cfg.eval if pi is None else 'TA-MRP'} {cfg.task} {cfg.error_mm:g}mm", row))
    if cfg.json:
        with open(cfg.json, "w") as f:
            json.dump(row, f, indent=2)
        print(f"wrote {cfg.json}")


def main(argv=None):
    def run(cfg):
        return run_evaluation(cfg) if cfg.eval else train(cfg)
    return cli.command("tacrl", lambda: run(parse_args(sys.argv[1:] if argv is None else list(argv))))


if __name__ == "__main__":
    sys.exit(main())
