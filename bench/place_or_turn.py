"""Which part of a location context costs a policy its success: the board moved, turned, or both?
A trained run is evaluated at one error range (the report's held-out seeds and trial count) in the
context, in the context's place without its turn, and in the training place with its turn.
Usage: python bench/place_or_turn.py RUN_DIR [--context loc-4] [--error-mm 20] [--episodes 20]"""
import argparse
import os
import sys

import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tools"))
import evaluate  # noqa: E402
import report  # noqa: E402
import scene  # noqa: E402
import sim  # noqa: E402
import tacrl  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run_dir")
    ap.add_argument("--context", default="loc-4", choices=[c for c in sim.CONTEXTS if c.startswith("loc-")])
    ap.add_argument("--error-mm", type=float, default=20.0)
    ap.add_argument("--episodes", type=int, default=20)
    a = ap.parse_args()
    torch.set_num_threads(1)
    run = report.load_run(a.run_dir)
    cfg, ctx = run["cfg"], sim.CONTEXTS[a.context]
    act = report.load_policy(run)
    sim.CONTEXTS["place only"] = scene.Context(board_xy=ctx.board_xy, board_yaw=0.0)
    sim.CONTEXTS["turn only"] = scene.Context(board_yaw=ctx.board_yaw)
    print(f"{a.run_dir}, {a.error_mm:g} mm, {a.episodes} held-out trials: SR, mean cumulative reward")
    for name in ("train", a.context, "place only", "turn only"):
        with evaluate.eval_env(cfg["task"], act, name, cfg["roi"], cfg["clearance_mm"]) as env:
            row = tacrl.evaluate_levels(env, act, (a.error_mm,), a.episodes, evaluate.EVAL_SEED + cfg["seed"],
                                        log=lambda *_: None)[0]
        print(f"  {name:11s} {row['success_rate']:.2f}  {row['cumulative_reward'][0]:7.1f}", flush=True)


if __name__ == "__main__":
    main()
