"""What the wrist sensor's drift rate does to results: trained runs (and the hand-designed policy, and the
two-step baseline) evaluated with scene.FT_DRIFT scaled by each factor, on the same held-out episodes.

No data sheet gives a drift rate (README difference 15). Scale 1 is ours (3 sigma reaches the FT 300's
1 N contact threshold in a 24 s episode: 0.068 N / sqrt(s)); scale 2.1 is the one published measurement
we found: a UR e-series wrist sensor, zeroed, the arm still, read (0.27, 1.38, 4.02) N off zero about
5 min later (github.com/UniversalRobots/Universal_Robots_ROS_Driver/issues/633), which as a random walk
is sqrt((0.27^2 + 1.38^2 + 4.02^2) / (3 x 300 s)) = 0.142 N / sqrt(s) per axis. Scale 0: no drift.
Usage: python bench/drift_effect.py RUN_DIR|initial|two-step ... [--task peg] [--scales 0 1 2.1]
       [--error-mm 20] [--episodes 20]   (initial is evaluated at 0 mm as well)"""
import argparse
import os
import sys

import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tools"))
import evaluate  # noqa: E402
import baselines  # noqa: E402
import report  # noqa: E402
import scene  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("policies", nargs="+", help="run dirs, or initial / two-step (with --task)")
    ap.add_argument("--task", default="peg", choices=("peg", "gear"), help="for initial and two-step")
    ap.add_argument("--scales", type=float, nargs="+", default=[0.0, 1.0, 2.1])
    ap.add_argument("--error-mm", type=float, default=20.0)
    ap.add_argument("--episodes", type=int, default=20)
    a = ap.parse_args()
    torch.set_num_threads(1)
    drift = scene.FT_DRIFT.copy()
    print(f"{a.episodes} held-out trials each: SR, mean cumulative reward, at each drift scale "
          f"({' / '.join(f'{k:g}' for k in a.scales)})", flush=True)
    for name in a.policies:
        if name in baselines.NAMES:
            task, seed, pi = a.task, 0, None
            levels = (0.0, a.error_mm) if name == "initial" else (a.error_mm,)
        else:
            run = report.load_run(name)
            task, seed = run["cfg"]["task"], run["cfg"]["seed"]
            pi = report.load_policy(run)
            levels = (a.error_mm,)
        for mm in levels:
            cells = []
            for k in a.scales:
                scene.FT_DRIFT = drift * k            # read by World.wrench_tool at every reading
                with evaluate.eval_env(task, pi, e_r_mm=mm) as env:
                    act = pi if pi is not None else baselines.make(name, env)
                    row = evaluate.evaluate(env, act, a.episodes, evaluate.EVAL_SEED + seed, log=lambda *_: None)
                cells.append(f"{row['success_rate']:.2f} {row['cumulative_reward'][0]:6.1f}")
            print(f"  {name:40s} {task:4s} {mm:4.0f} mm   " + "   ".join(cells), flush=True)
    scene.FT_DRIFT = drift


if __name__ == "__main__":
    main()
