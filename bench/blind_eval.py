"""Does a trained policy use its image? Each run's held-out evaluation at one error range replayed (the seeds of
eval.json, so the same episodes) three ways: the image as seen; the image frozen at the episode's first one (no
closed-loop vision: what the tool's motion brings into view is not seen); and blank (every pixel the first image's
mean: no vision at all). Pose and wrench histories are as seen in each.

    python bench/blind_eval.py RUN_DIR [RUN_DIR ...] [--error-mm 20] [--episodes 20]

Prints a line a run: its success rate each way. 'seen' repeats eval.json's row at that range.
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

MODES = ("seen", "frozen", "blank")


def with_image(act, env, mode):
    """act(obs), its image replaced as `mode` says (the env's step count tells an episode's first step)."""
    first = {}

    def blind(obs):
        if env.steps == 0:
            first["image"] = obs["image"].copy()
        if mode != "seen":
            img = first["image"] if mode == "frozen" else np.full_like(first["image"], int(first["image"].mean()))
            obs = {**obs, "image": img}
        return act(obs)
    if hasattr(act, "reset"):
        blind.reset = act.reset
    return blind


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--error-mm", type=float, default=20.0)
    ap.add_argument("--episodes", type=int, default=20)
    a = ap.parse_args()
    torch.set_num_threads(1)
    for d in a.runs:
        run = report.load_run(d)
        act, cfg = report.load_policy(run), run["cfg"]
        sr = {}
        with evaluate.eval_env(cfg["task"], act, roi=cfg["roi"], e_r_mm=a.error_mm) as env:
            for mode in MODES:
                row = evaluate.evaluate(env, with_image(act, env, mode), a.episodes, evaluate.EVAL_SEED + cfg["seed"],
                                        log=lambda *_: None)
                sr[mode] = row["success_rate"]
        print(f"{d}  roi {cfg['roi']}  obs {cfg['obs']}  SR at {a.error_mm:g} mm: " +
              "  ".join(f"{m} {sr[m]:.2f}" for m in MODES), flush=True)


if __name__ == "__main__":
    main()
