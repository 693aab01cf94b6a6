"""tacrl.py: command line of tacrl, the companion code of Wang et al., "Task attention-based multimodal
fusion and curriculum residual learning for context generalization in robotic assembly" (2024).

This first cut rolls out the hand-designed policy alone (trajectory + compliance, F_d = 0; paper
Sec. 4.1) and prints a Table-1-style row. Training (Algorithm 1) comes with policy.py.

    python tacrl.py --task peg --eval initial --error-mm 0 --episodes 20
    python tacrl.py --task gear --eval initial --error-mm 20 --episodes 20 --json gear20.json
    python tacrl.py --task peg --eval initial --context loc-1 --video peg.mp4
"""
import argparse
import json
import sys
import time
from dataclasses import dataclass, fields

import numpy as np

import sim


@dataclass
class Args:
    task: str = "peg"            # 'peg' (0.1 mm clearance) or 'gear' (Sec. 5.1.1)
    eval: str = "initial"        # what to evaluate: 'initial' = the hand-designed policy alone
    error_mm: float = 0.0        # E_r, the error range of X^_i and X^_g, mm (Eq. 13-15)
    episodes: int = 20           # evaluation episodes (the paper: 20 test trials)
    context: str = "train"       # board location / background (sim.CONTEXTS)
    roi: str = "task"            # 'task' (Eq. 11) or a preset of the ROI ablation
    clearance_mm: float = 0.1    # diametral clearance, mm
    seed: int = 0                # seeds the errors of every episode
    json: str = ""               # also write the row as JSON to this file
    video: str = ""              # record the first episode from an external camera (.mp4)
    gui: bool = False            # open the PyBullet window


HELP = {
    "task": "peg or gear", "eval": "'initial': the hand-designed policy alone",
    "error_mm": "error range E_r in mm (0..30)", "episodes": "number of evaluation episodes",
    "context": f"one of {', '.join(sim.CONTEXTS)}", "roi": f"task or one of {', '.join(sim.ROI_PRESETS)}",
    "clearance_mm": "diametral clearance of the peg / gear bore, mm", "seed": "random seed",
    "json": "write the result row to this JSON file", "video": "record the first episode to this .mp4",
    "gui": "open the PyBullet GUI",
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
    if a.task not in ("peg", "gear"):
        raise ArgError(f"--task must be peg or gear, not {a.task!r}")
    if a.eval != "initial":
        raise ArgError(f"--eval {a.eval!r}: only 'initial' exists so far (trained policies arrive with training)")
    if not 0.0 <= a.error_mm <= 30.0:
        raise ArgError(f"--error-mm must be within 0..30, not {a.error_mm}")
    if a.episodes < 1:
        raise ArgError(f"--episodes must be at least 1, not {a.episodes}")
    if a.context not in sim.CONTEXTS:
        raise ArgError(f"--context must be one of {', '.join(sim.CONTEXTS)}, not {a.context!r}")
    if a.roi != "task" and a.roi not in sim.ROI_PRESETS:
        raise ArgError(f"--roi must be task or one of {', '.join(sim.ROI_PRESETS)}, not {a.roi!r}")
    if not 0.0 < a.clearance_mm <= 2.0:
        raise ArgError(f"--clearance-mm must be within (0, 2], not {a.clearance_mm}")
    if a.video and not a.video.endswith(".mp4"):
        raise ArgError(f"--video must name an .mp4 file, not {a.video!r}")
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


def main(argv=None):
    try:
        a = parse_args(argv)
    except ArgError as e:
        print(f"tacrl: error: {e}", file=sys.stderr)
        return 2
    print("config:", vars(a) if hasattr(a, "__dict__") else a)
    env = sim.AssemblyEnv(a.task, a.context, e_r=a.error_mm / 1000, roi=a.roi, clearance=a.clearance_mm / 1000,
                          gui=a.gui)
    video = None
    if a.video:
        import cv2
        frame = env.world.render_external()
        video = cv2.VideoWriter(a.video, cv2.VideoWriter_fourcc(*"mp4v"), sim.POLICY_HZ, frame.shape[1::-1])
    try:
        row = evaluate(env, lambda obs: np.zeros(6), a.episodes, a.seed, video)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        if video is not None:
            video.release()
        env.close()
    row.update({"task": a.task, "policy": "initial", "error_mm": a.error_mm, "context": a.context, "roi": a.roi,
                "seed": a.seed})
    print(format_row(f"initial {a.task} {a.error_mm:g}mm", row))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(row, f, indent=2)
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
