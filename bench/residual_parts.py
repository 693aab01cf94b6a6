"""What part of its residual a policy inserts with: a trained run rolled out on the report's held-out seeds
with its whole action F_d, with its torques zeroed (the forces kept), and with the residual zeroed (the
hand-designed part of Eq. 6 alone). For each: success rate, the mean action (in F_max/2 units, task frame:
fx fy fz tx ty tz, +z into the part) and where the tip ended, sideways and above full depth, in mm.
Usage: python bench/residual_parts.py RUN_DIR [--error-mm 5] [--episodes 5]"""
import argparse
import os
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tools"))
import evaluate  # noqa: E402
import report  # noqa: E402
import sim  # noqa: E402

VARIANTS = {"whole residual": np.ones(6), "torques zeroed": np.r_[1, 1, 1, 0, 0, 0.0], "no residual": np.zeros(6)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run_dir")
    ap.add_argument("--error-mm", type=float, default=5.0)
    ap.add_argument("--episodes", type=int, default=5)
    a = ap.parse_args()
    torch.set_num_threads(1)
    run = report.load_run(a.run_dir)
    cfg, pi = run["cfg"], report.load_policy(run)
    print(f"{a.run_dir}, {a.error_mm:g} mm, {a.episodes} held-out trials")
    with evaluate.eval_env(cfg["task"], pi, "train", cfg["roi"], cfg["clearance_mm"], a.error_mm) as env:
        for name, keep in VARIANTS.items():
            wins, acts, ends = 0, [], []

            def act(obs):                                                  # the policy's F_d, parts zeroed
                acts.append(np.asarray(pi(obs)) * keep)
                return acts[-1]

            for k in range(a.episodes):
                offs = []
                seed = evaluate.episode_seed(evaluate.EVAL_SEED + cfg["seed"], k)
                term, _, _ = sim.run_episode(env, act, seed=seed,
                                             on_step=lambda obs, r, info: offs.append(info["goal_offset"][:3]))
                wins += int(term)
                ends.append(np.asarray(offs[-1]) * 1000)                  # m -> mm
            ends = np.array(ends)
            side, up = np.hypot(ends[:, 0], ends[:, 1]), ends[:, 2]
            print(f"  {name:15s} SR {wins / a.episodes:.2f}  mean action {np.round(np.mean(acts, 0), 2)}  "
                  f"end: {side.min():.1f}-{side.max():.1f} sideways, {up.min():.1f}-{up.max():.1f} above", flush=True)


if __name__ == "__main__":
    main()
