"""Policy steps per second of the env with the camera on (the hand-designed policy, F_d = 0), and what
a reset costs.

    python bench/bench_env.py [--steps 200] [--repeats 5]

Each repeat runs `steps` policy steps (24 controller ticks, 48 physics steps and one 80 x 80
TinyRenderer image each) on one core, resets included; prints the median and the spread. Target:
>= 50 steps/s. Then the median time of a reset (since issue 19 it rebuilds the world, so that an
episode depends on its seed only) and of a whole 120-step episode with its reset.
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


def reset_and_episode_seconds(task, repeats):
    """Median seconds of a reset, and of a reset plus a full episode at 20 mm (F_d = 0: 120 steps)."""
    env = sim.AssemblyEnv(task, e_r=0.02)
    resets, episodes = [], []
    for k in range(repeats):
        t0 = time.perf_counter()
        env.reset(seed=k)
        resets.append(time.perf_counter() - t0)
        done = False
        while not done:
            _, _, term, trunc, _ = env.step(np.zeros(6))
            done = term or trunc
        episodes.append(time.perf_counter() - t0)
    env.close()
    return np.median(resets), np.median(episodes)


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
        reset, episode = reset_and_episode_seconds(task, a.repeats)
        print(f"{task:4s} reset: median {reset * 1000:5.1f} ms; an episode with its reset: median {episode:5.2f} s")


if __name__ == "__main__":
    main()
