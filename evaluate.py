"""evaluate.py: the paper's evaluation (Sec. 5.1.3, Tables 1-2) of a trained policy, of the hand-designed
policy alone or of a baseline, on held-out seeds; and a video of an episode that a browser plays.

    row = evaluate(env, act, episodes=20, seed=EVAL_SEED)   # act(obs) -> action in [-1, 1]^6
    rows = evaluate_levels(env, pi, (5, 10, 15, 20), 20, EVAL_SEED)   # Table 2: each error range E_r, mm

A row holds the success rate (SR), the completion time of the successful episodes (CT, s), the peak
contact force per world axis in each episode (CF, N) and the cumulative reward (CR), each as
[mean, std] over the episodes. tacrl.py's --eval, the report and the benches evaluate through here.
"""
import os
import time

import cv2
import numpy as np

import policy
import rundir
import scene
import sim

POLICY_FORMAT = "tacrl-policy-2"
EVAL_SEED = 1000             # evaluation episodes use seeds from EVAL_SEED + the run's seed: never a training seed
POLICY_META = ("task", "roi", "vanilla", "ex_r", "e_r_max")     # what training tells evaluation (tacrl.finish)


def save_policy(path, sac, meta):
    """policy.pt: the actor and the encoder it reads (the critics stay behind), and meta, a dict of
    plain values that evaluation must know of training ('obs' among them: the encoder's kind)."""
    rundir.save_atomic({"format": POLICY_FORMAT, **meta, "norm": sac.actor_enc.norm_kind,
                 "image_norm": sac.actor_enc.image_norm, "encoder": sac.actor_enc.state_dict(),
                 "actor": sac.actor.state_dict()}, path)


class TrainedPolicy:
    """A policy.pt's contents (torch.load) as act(obs) -> action: the deterministic actor (the
    Gaussian's mean). .meta holds what save_policy was given."""

    def __init__(self, d, device="cpu"):
        if not isinstance(d, dict) or d.get("format") != POLICY_FORMAT:
            raise ValueError("not a tacrl policy file")
        self.meta = {k: v for k, v in d.items() if k not in ("format", "encoder", "actor")}
        self.device = device
        if (d.get("image_encoder", "cnn"), d.get("image_feat", policy.FEAT)) != ("cnn", policy.FEAT):
            raise ValueError(f"its image encoder ({d['image_encoder']}, {d['image_feat']}-d) is the critics study's "
                             "(docs/CRITICS.md names the git tag that reads it)")
        # (files before 'norm' and 'image_norm': joint, fixed)
        self.encoder = policy.Encoder(d["obs"], norm=d.get("norm", "joint"), image_norm=d.get("image_norm", "fixed"))
        self.encoder.to(device).eval()
        self.encoder.load_state_dict(d["encoder"])
        self.actor = policy.Actor(self.encoder.out_dim).to(device).eval()
        self.actor.load_state_dict(d["actor"])

    def __call__(self, obs):
        return policy.act(self.encoder, self.actor, obs, deterministic=True, device=self.device)


def load_policy(path, device="cpu"):
    """policy.pt -> TrainedPolicy; ValueError saying what is wrong with a file that is not one."""
    try:
        pi = TrainedPolicy(rundir.load_file(path, device), device)
    except Exception as e:          # corrupt, truncated, foreign: one phrase for the caller's line
        lines = str(e).strip().splitlines()
        raise ValueError(f"cannot load the policy ({type(e).__name__}{': ' + lines[0][:120] if lines else ''})")
    missing = set(POLICY_META) - set(pi.meta)
    if missing:
        raise ValueError(f"cannot load the policy (its meta lacks {', '.join(sorted(missing))})")
    return pi


def eval_env(task, act, context="train", roi="task", clearance_mm=0.1, e_r_mm=0.0, gui=False):
    """The env to evaluate `act` in; a TrainedPolicy's at the Ex_r, ROI and X_i it was trained for, with its
    guidance."""
    m = act.meta if isinstance(act, TrainedPolicy) else {}
    return sim.AssemblyEnv(task, context, e_r=e_r_mm / 1000, ex_r=m.get("ex_r"), roi=roi, clearance=clearance_mm / 1000,
                           gui=gui, base_policy=not m.get("vanilla", False), e_r_max=m.get("e_r_max"),
                           keypoint=m.get("obs") == "ts-ptk")


def episode_seed(seed, k):
    """The seed of evaluation episode k of an evaluation seeded `seed` (evaluate's; a replay of it uses the same)."""
    return seed * 100003 + k


def evaluate(env, act, episodes, seed, video=None, log=print):
    """Roll out act(obs) -> action for `episodes` episodes (episode k's seed: episode_seed(seed, k)); returns the
    Table-1/2 row: success rate, completion time of the successful episodes (s), peak |contact force|
    per world axis in each episode (N) and cumulative reward, each as [mean, std]. video: an open_video
    writer that gets the first episode, a frame a policy step."""
    succ, times, forces, returns = [], [], [], []
    t0 = time.time()
    for ep in range(episodes):
        peak = np.zeros(3)

        def on_step(obs, r, info, first=ep == 0):
            np.maximum(peak, np.abs(info["f_world"][:3]), out=peak)
            if video is not None and first:
                video.write(env.world.render_external()[:, :, ::-1])     # RGB -> OpenCV's BGR
        term, info, ret = sim.run_episode(env, act, seed=episode_seed(seed, ep), on_step=on_step)
        succ.append(term)
        returns.append(ret)
        forces.append(peak)
        if term:
            times.append(info["t"])
        el = time.time() - t0
        eta = el / (ep + 1) * (episodes - ep - 1)
        log(f"episode {ep + 1}/{episodes}  success {int(term)}  time {info['t']:5.1f}s  return {ret:7.1f}  "
            f"|F|max x/y/z {peak[0]:5.1f}/{peak[1]:5.1f}/{peak[2]:5.1f} N  elapsed {el:5.0f}s  ETA {eta:4.0f}s")
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
    def ms(k, f="{:.2f}"):
        return "-" if row[k] is None else f"{f.format(row[k][0])} +- {f.format(row[k][1])}"
    return (f"{'policy':<22} {'SR':>5}  {'CT (s)':>14}  {'Fx (N)':>14}  {'Fy (N)':>14}  {'Fz (N)':>14}  {'CR':>16}\n"
            f"{name:<22} {row['success_rate']:5.2f}  {ms('completion_time_s'):>14}  {ms('contact_force_x_N'):>14}  "
            f"{ms('contact_force_y_N'):>14}  {ms('contact_force_z_N'):>14}  {ms('cumulative_reward', '{:.1f}'):>16}")


# ---------------------------------------------------------------- a video a browser plays
VIDEO_CODECS = {".webm": ("VP90", "VP9"), ".mp4": ("avc1", "H.264")}   # what browsers play (MDN's video codec guide)


def open_video(path, size, fps=sim.POLICY_HZ):
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
