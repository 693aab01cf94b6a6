"""evaluate.py: the paper's evaluation (Sec. 5.1.3, Tables 1-2) of a trained policy, of the hand-designed
policy alone or of a baseline, on held-out seeds; and a video of an episode that a browser plays.

    row = evaluate(env, act, episodes=20, seed=EVAL_SEED)   # act(obs) -> action in [-1, 1]^6
    rows = evaluate_levels(env, pi, (5, 10, 15, 20), 20, EVAL_SEED)   # Table 2: each error range E_r, mm

A row holds the success rate (SR), the completion time of the successful episodes (CT, s), the peak
contact force per world axis in each episode (CF, N) and the cumulative reward (CR), each as
[mean, std] over the episodes. tacrl.py's --eval, the report and the benches evaluate through here.
"""
import contextlib
import os
import pickle
import socket
import subprocess
import sys
import threading
import time

import cv2
import numpy as np
import torch

import tacrl_flat  # noqa: F401  (first: where another package shadows one of our modules, one line says so)
import policy
import rundir
import scene
import sim

POLICY_FORMAT = "tacrl-policy-2"
EVAL_SEED = 1000             # evaluation episodes use seeds from EVAL_SEED + the run's seed: never a training seed
POLICY_META = ("task", "roi", "vanilla", "ex_r", "e_r_max")     # what training tells evaluation (tacrl.finish)
VIDEO_FPS = 20               # a video's frames a second of simulated time: one every 6 of the 120 Hz controller's ticks


def policy_file(sac, meta):
    """What policy.pt holds: the actor and the encoder it reads (the critics stay behind), and meta, a dict of
    plain values that evaluation must know of training ('obs' among them: the encoder's kind)."""
    return {"format": POLICY_FORMAT, **meta, "norm": sac.actor_enc.norm_kind, "image_norm": sac.actor_enc.image_norm,
            "encoder": sac.actor_enc.state_dict(), "actor": sac.actor.state_dict()}


def save_policy(path, sac, meta):
    rundir.save_atomic(policy_file(sac, meta), path)


class TrainedPolicy:
    """A policy.pt's contents (torch.load) as act(obs) -> action: the deterministic actor (the
    Gaussian's mean). .meta holds what save_policy was given."""

    def __init__(self, d, device="cpu"):
        if not isinstance(d, dict) or d.get("format") != POLICY_FORMAT:
            raise ValueError("not a tacrl policy file")
        self.meta = {k: v for k, v in d.items() if k not in ("format", "encoder", "actor")}
        self.file = d                                           # (what a Worker is sent to play the same policy)
        self.device = device
        if (d.get("image_encoder", "cnn"), d.get("image_feat", policy.FEAT)) != ("cnn", policy.FEAT):
            raise ValueError(f"its image encoder ({d['image_encoder']}, {d['image_feat']}-d) is the critics study's "
                             "(docs/critics.md names the commit that reads it)")
        # (files before 'norm' and 'image_norm': joint, fixed). The layers' first weights, overwritten at once, are
        # drawn on a fork of torch's generator: a training run that copies its policy to validate it trains on as if
        # it had not (tacrl.validate)
        with torch.random.fork_rng(devices=[]):
            self.encoder = policy.Encoder(d["obs"], norm=d.get("norm", "joint"),
                                          image_norm=d.get("image_norm", "fixed"))
            self.actor = policy.Actor(self.encoder.out_dim)
        self.encoder.to(device).eval()
        self.encoder.load_state_dict(d["encoder"])
        self.actor.to(device).eval()
        self.actor.load_state_dict(d["actor"])

    def __call__(self, obs):
        """obs: the env's observation -> action (6,); or a vector env's batch of them -> (B, 6)."""
        return policy.act(self.encoder, self.actor, obs, deterministic=True, device=self.device)


def load_policy(path, device="cpu", from_checkpoint=None):
    """policy.pt -> TrainedPolicy; ValueError saying what is wrong with a file that is not one. from_checkpoint(path,
    contents) -> a policy file's contents, where given, reads a training checkpoint too (tacrl.checkpoint_policy)."""
    try:
        d = rundir.load_file(path, device)
        if from_checkpoint is not None and isinstance(d, dict) and "sac" in d and "format" not in d:
            d = from_checkpoint(path, d)
        pi = TrainedPolicy(d, device)
    except Exception as e:          # corrupt, truncated, foreign: one phrase for the caller's line
        lines = str(e).strip().splitlines()
        raise ValueError(f"cannot load the policy ({type(e).__name__}{': ' + lines[0][:120] if lines else ''})")
    missing = set(POLICY_META) - set(pi.meta)
    if missing:
        raise ValueError(f"cannot load the policy (its meta lacks {', '.join(sorted(missing))})")
    return pi


def env_kwargs(pi):
    """sim.AssemblyEnv's keyword arguments for a TrainedPolicy: the view, Ex_r, tilt and X_i it was trained for, with
    its guidance (none for the vanilla baseline) and, for keypoint RL, the keypoint. gym.make takes them too."""
    m = pi.meta
    return dict(roi=m.get("roi", "task"), ex_r=m.get("ex_r"), e_r_max=m.get("e_r_max"),
                base_policy=not m.get("vanilla", False),
                keypoint=m.get("obs") == "ts-ptk", tilt=m.get("tilt", 0.0))      # (files before tilt: 0)


def eval_env(task, act, context="train", roi="task", clearance_mm=0.1, e_r_mm=0.0, gui=False):
    """The env to evaluate `act` in at E_r `e_r_mm`; a TrainedPolicy's as env_kwargs gives it (its view: `roi`)."""
    kw = {**env_kwargs(act), "roi": roi} if isinstance(act, TrainedPolicy) else {"roi": roi}
    return sim.AssemblyEnv(task, context, e_r=e_r_mm / 1000, clearance=clearance_mm / 1000, gui=gui, **kw)


def episode_seed(seed, k):
    """The seed of evaluation episode k of an evaluation seeded `seed` (evaluate's; a replay of it uses the same)."""
    return seed * 100003 + k


def play(env, act, seed, video=None):
    """One evaluation episode: (success, completion time s, peak |contact force| per world axis (3,) N, return).
    video: an open_video writer that gets VIDEO_FPS frames a second of the episode's simulated time, taken between
    the controller's ticks (the policy's 5 Hz alone plays as a slide show)."""
    peak, ticks = np.zeros(3), iter(range(10 ** 9))

    def on_step(obs, r, info):
        np.maximum(peak, np.abs(info["f_world"][:3]), out=peak)

    def frame():
        if next(ticks) % (scene.CONTROL_HZ // VIDEO_FPS) == 0:
            video.write(env.world.render_external()[:, :, ::-1])     # RGB -> OpenCV's BGR
    env.on_tick = frame if video is not None else None
    try:
        term, info, ret = sim.run_episode(env, act, seed=seed, on_step=on_step)
    finally:
        env.on_tick = None
    return bool(term), float(info["t"]), peak, float(ret)


def shares(act, episodes, worker):
    """Whether a Worker plays the odd episodes of an evaluation (a TrainedPolicy's, more than one)."""
    return worker is not None and isinstance(act, TrainedPolicy) and episodes > 1


def evaluate(env, act, episodes, seed, video=None, log=print, worker=None, later=0):
    """Roll out act(obs) -> action for `episodes` episodes (episode k's seed: episode_seed(seed, k)); returns the
    Table-1/2 row: success rate, completion time of the successful episodes (s), peak |contact force|
    per world axis in each episode (N) and cumulative reward, each as [mean, std]. video: an open_video
    writer that gets the first episode (VIDEO_FPS frames a second of its simulated time). worker: a Worker that
    plays the odd episodes of a TrainedPolicy meanwhile, on the second core (the same row: an episode depends on its
    seed only). log gets a line an episode; its ETA counts `later` episodes of this process still to come after
    these (evaluate_levels' next levels)."""
    shared = shares(act, episodes, worker)
    mine = range(0, episodes, 2) if shared else range(episodes)
    if shared:
        worker.start(env, act, [episode_seed(seed, k) for k in range(1, episodes, 2)])
    out, t0 = {}, time.time()

    def show(k, res, played):           # played: this process's episodes so far, for the time an episode takes
        el = time.time() - t0
        log(f"episode {k + 1}/{episodes}  success {int(res[0])}  time {res[1]:5.1f}s  return {res[3]:7.1f}  "
            f"|F|max x/y/z {res[2][0]:5.1f}/{res[2][1]:5.1f}/{res[2][2]:5.1f} N  elapsed {el:5.0f}s  "
            f"ETA {el / played * (len(mine) - played + later):4.0f}s")
    for i, k in enumerate(mine):
        out[k] = play(env, act, episode_seed(seed, k), video if k == 0 else None)
        show(k, out[k], i + 1)
    if shared:
        for k, res in zip(range(1, episodes, 2), worker.results()):
            out[k] = res
            show(k, res, len(mine))
    succ, times, forces, returns = zip(*(out[k] for k in range(episodes)))
    times, forces = [t for t, s in zip(times, succ) if s], np.array(forces)
    mean_std = lambda x: [float(np.mean(x)), float(np.std(x))] if len(x) else None   # noqa: E731 (None: no success)
    return {"success_rate": float(np.mean(succ)), "completion_time_s": mean_std(times),
            "contact_force_x_N": mean_std(forces[:, 0]), "contact_force_y_N": mean_std(forces[:, 1]),
            "contact_force_z_N": mean_std(forces[:, 2]), "cumulative_reward": mean_std(returns),
            "episodes": episodes}


def evaluate_levels(env, act, levels, episodes, seed, log=lambda row: None, worker=None, progress=lambda line: None):
    """Table-2 rows: `evaluate` at each error range E_r in `levels` (mm), with Ex_r held where the
    policy's training ended (the controller stays as trained). log gets each row; progress a line an episode,
    its ETA over every level."""
    rows, here = [], len(range(0, episodes, 2 if shares(act, episodes, worker) else 1))   # this process's a level
    for i, mm in enumerate(levels):
        env.set_ranges(mm / 1000, act.meta["ex_r"])
        row = evaluate(env, act, episodes, seed, log=lambda line: progress(f"eval {mm:g} mm  {line}"), worker=worker,
                       later=here * (len(levels) - i - 1))
        row.update(error_mm=mm, ex_r_mm=round(env.ex_r * 1000, 3))
        rows.append(row)
        log(row)
    return rows


def format_row(name, row):
    def ms(k, f="{:.2f}"):
        return "-" if row[k] is None else f"{f.format(row[k][0])} +- {f.format(row[k][1])}"
    return (f"{'policy':<22} {'SR':>5}  {'CT (s)':>14}  {'Fx (N)':>14}  {'Fy (N)':>14}  {'Fz (N)':>14}  {'CR':>16}\n"
            f"{name:<22} {row['success_rate']:5.2f}  {ms('completion_time_s'):>14}  {ms('contact_force_x_N'):>14}  "
            f"{ms('contact_force_y_N'):>14}  {ms('contact_force_z_N'):>14}  {ms('cumulative_reward', '{:.1f}'):>16}")


# ---------------------------------------------------------------- the second core
class Worker:
    """A second process that plays some of an evaluation's episodes while this one plays the rest, so that
    evaluation uses both cores as the updates do. Every episode is a fresh world drawn from its seed alone
    (sim.AssemblyEnv.reset), so who plays it changes nothing. A TrainedPolicy's weights travel to it (as
    policy.pt holds them), and the env's constructor arguments (sim.AssemblyEnv.init_kwargs). CPU only: a GPU
    policy's numbers would differ from the worker's. Use it as a context manager; it is started at once, so
    that its imports overlap other work, and ends when this process closes it or ends."""

    def __init__(self):
        here, there = socket.socketpair()
        code = f"import sys; sys.path.insert(0, {os.path.dirname(os.path.abspath(__file__))!r}); " \
               "import evaluate; evaluate.serve(int(sys.argv[1]))"
        # its own session: a Ctrl-C in the terminal reaches this process, which closes the socket, and not the worker
        self.proc = subprocess.Popen([sys.executable, "-c", code, str(there.fileno())], pass_fds=(there.fileno(),),
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, start_new_session=True)
        there.close()
        self.sock, self.sender, self.busy = here, None, False
        self.stream = here.makefile("rwb")

    def start(self, env, pi, seeds):
        """Play pi in an env built as `env` is, at its E_r and Ex_r, with these episode seeds (results() gives them)."""
        job = (env.init_kwargs, env.e_r, env.ex_r, pi.file, list(seeds))
        self.busy = True
        self.sender = threading.Thread(target=self._send, args=(job,))   # (it may still be importing: no waiting here)
        self.sender.start()

    def _send(self, job):
        try:
            pickle.dump(job, self.stream)
            self.stream.flush()
        except OSError:                         # it died: results() says so
            pass

    def results(self):
        """[play's (success, time, peak force, return)] of the seeds given to start, in their order."""
        self.sender.join()
        try:
            out = pickle.load(self.stream)
        except (EOFError, OSError):
            raise RuntimeError("the evaluation worker process ended (its error is printed above)") from None
        self.busy = False
        return out

    def close(self):
        """End it: at once if it is playing episodes no one will read (an interrupted evaluation)."""
        if self.busy:
            self.proc.kill()
        self.stream.close()
        self.sock.close()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def second_core(cores, device="cpu"):
    """A Worker where a run may use 2 cores and its policy runs on the CPU; else a context that gives None."""
    return Worker() if cores > 1 and str(device) in ("cpu", "auto") else contextlib.nullcontext()


def serve(fd):
    """The Worker's process: (env kwargs, E_r, Ex_r, policy file, seeds) -> [play(...) of each seed], until EOF."""
    import torch
    torch.set_num_threads(1)                            # one core: the other is the process that sent the work
    stream, env, built = socket.socket(fileno=fd).makefile("rwb"), None, None
    try:
        while True:
            try:
                kwargs, e_r, ex_r, d, seeds = pickle.load(stream)
            except EOFError:
                return
            if kwargs != built:
                if env is not None:
                    env.close()
                env, built = sim.AssemblyEnv(**kwargs), kwargs
            env.set_ranges(e_r, ex_r)
            pi = TrainedPolicy(d)
            out = [play(env, pi, s) for s in seeds]
            try:
                pickle.dump(out, stream)
                stream.flush()
            except OSError:                             # the process that asked has gone
                return
    finally:
        if env is not None:
            env.close()


# ---------------------------------------------------------------- a video a browser plays
VIDEO_CODECS = {".webm": ("VP90", "VP9"), ".mp4": ("avc1", "H.264")}   # what browsers play (MDN's video codec guide)


def open_video(path, size, fps=VIDEO_FPS):
    """A cv2.VideoWriter of (w, h) BGR frames, its codec chosen by the extension (.webm: VP9, .mp4: H.264);
    ValueError where this OpenCV cannot write that format (OpenCV's pip wheels encode VP9 with libvpx but
    carry no H.264 encoder). Release it inside scene.quiet_c_output(): FFmpeg prints as it closes."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in VIDEO_CODECS:
        raise ValueError("a video is a .webm (VP9) or .mp4 (H.264) file")
    fourcc, codec = VIDEO_CODECS[ext]
    with scene.quiet_c_output():                   # FFmpeg's notices (a codec tag it does not know for WebM)
        writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*fourcc), fps, size)
    if not writer.isOpened():
        hint = "; name a .webm file instead (VP9, which every current browser plays)" if ext == ".mp4" else ""
        raise ValueError(f"this OpenCV ({cv2.__version__}) has no {codec} encoder{hint}")
    return writer
