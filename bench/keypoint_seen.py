"""Does keypoint RL fail where its detector loses the hole? Each run's held-out evaluation at one error range
replayed (the seeds of eval.json, so the same episodes), with, for each episode, the share of policy steps whose
image gave a keypoint (sim.hole_keypoint found the hole) and whether the first one did.

    python bench/keypoint_seen.py RUN_DIR [RUN_DIR ...] [--error-mm 20] [--episodes 20]

Prints a line an episode, then, over all runs, the success rate of the episodes whose first image had the hole
and of those whose first image had not, and the mean share of steps with a keypoint in successes and failures.
"""
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--error-mm", type=float, default=20.0)
    ap.add_argument("--episodes", type=int, default=20)
    a = ap.parse_args()
    torch.set_num_threads(1)
    rows = []                                          # (found at the first step, share of steps found, success)
    for d in a.runs:
        run = report.load_run(d)
        act, seed = report.load_policy(run), evaluate.EVAL_SEED + run["cfg"]["seed"]
        with evaluate.eval_env("peg", act, e_r_mm=a.error_mm) as env:
            for k in range(a.episodes):
                found = []

                def act_seeing(obs):
                    found.append(bool(obs["keypoint"][3]))
                    return act(obs)
                success, _, _ = sim.run_episode(env, act_seeing, seed=evaluate.episode_seed(seed, k))
                rows.append((found[0], np.mean(found), bool(success)))
                print(f"{d}  episode {k}  keypoint at the start {int(found[0])}  steps with a keypoint "
                      f"{np.mean(found):.2f} of {len(found)}  success {int(success)}", flush=True)
    r = np.array(rows, float)
    for v, name in ((1, "had"), (0, "had not")):
        sel = r[r[:, 0] == v]
        print(f"first image {name} the hole: {len(sel)} episodes, SR {sel[:, 2].mean() if len(sel) else float('nan'):.2f}")
    for v, name in ((1, "successes"), (0, "failures")):
        sel = r[r[:, 2] == v]
        print(f"{name}: {len(sel)} episodes, steps with a keypoint {sel[:, 1].mean() if len(sel) else float('nan'):.2f}")


if __name__ == "__main__":
    main()
