"""Policy steps per second of the env with the camera on (the hand-designed policy, F_d = 0).

    python bench/bench_env.py [--steps 200] [--repeats 5]

Each repeat runs `steps` policy steps (24 controller ticks, 48 physics steps and one 80 x 80
TinyRenderer image each) on one core; prints the median and the spread. Target: >= 50 steps/s.
"""
import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import sim  # noqa: E402


def rate(task, steps, image=True):
    env = sim.AssemblyEnv(task, e_r=0.02, image=image)
    env.reset(seed=0)
    n, t0 = 0, time.perf_counter()
    while n < steps:
        _, _, term, trunc, _ = env.step(np.zeros(6))
        n += 1
        if term or trunc:
            env.reset()
    dt = time.perf_counter() - t0
    env.close()
    return n / dt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    for task in ("peg", "gear"):
        for image in (True, False):
            r = [rate(task, a.steps, image) for _ in range(a.repeats)]
            print(f"{task:4s} camera {'on ' if image else 'off'}: median {np.median(r):6.1f} policy steps/s "
                  f"(min {min(r):.1f}, max {max(r):.1f}, {a.repeats} x {a.steps} steps)")


if __name__ == "__main__":
    main()
