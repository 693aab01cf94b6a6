"""SAC gradient updates per second, and env plus update time per training episode.

    python bench/bench_sac.py [--updates 60] [--repeats 3] [--batch 64]

1. Updates/s of policy.SAC at the given batch on random data of the env's shapes, for each
   observation variant with the paper's critics (--critic multimodal: the actor reads their
   encoder), and for the TA-MRP with privileged critics (the default: no image encoder in the
   critics, the actor has its own).
2. One training episode as tacrl.py runs it by default: the policy acting in the env for 120 steps at the
   final 20 mm error range (camera on, an untrained actor), then 200 updates (the paper's count).
Prints medians over `repeats`; the machine is shared and noisy, so compare ratios.
"""
import argparse
import os
import sys
import time

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import command  # noqa: E402
import policy  # noqa: E402
import sim  # noqa: E402
import tacrl  # noqa: E402

SHAPES = {"image": (1, sim.IMG, sim.IMG), "pose_hist": (sim.HIST, 6), "wrench_hist": (sim.HIST, 6),
          "state": (tacrl.STATE_DIM,), "extra": (tacrl.EXTRA_DIM,)}   # what the privileged, the paper's critics read


def filled_buffer(rng, n=2000):
    buf = policy.ReplayBuffer(n, SHAPES)
    T = n // 10
    for _ in range(10):
        buf.add_episode({"obs": {"image": rng.integers(0, 256, (T + 1, 1, sim.IMG, sim.IMG), dtype=np.uint8),
                                 "pose_hist": rng.normal(0, 0.01, (T + 1, sim.HIST, 6)).astype(np.float32),
                                 "wrench_hist": rng.normal(0, 1, (T + 1, sim.HIST, 6)).astype(np.float32),
                                 "state": rng.normal(0, 1, (T + 1, tacrl.STATE_DIM)).astype(np.float32),
                                 "extra": rng.uniform(0, 1, (T + 1, tacrl.EXTRA_DIM)).astype(np.float32)},
                         "act": rng.uniform(-1, 1, (T, 6)), "rew": rng.normal(size=T), "term": np.zeros(T)})
    return buf


def updates_per_s(sac, buf, rng, batch, n):
    for _ in range(3):
        sac.update(buf.sample(batch, rng))
    t0 = time.perf_counter()
    for _ in range(n):
        sac.update(buf.sample(batch, rng))
    return n / (time.perf_counter() - t0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--updates", type=int, default=60)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--batch", type=int, default=64)
    a = ap.parse_args()
    command.use_cpu()          # as a run: one torch thread an op, malloc keeping what it frees
    rng = np.random.default_rng(0)
    buf = filled_buffer(rng)
    threads = tacrl.make_sac(tacrl.Config(), "cpu").helper.threads
    print(f"torch {torch.__version__}, {threads} threads an update (the batch's halves side by side), batch {a.batch}")
    for obs, critic in (("ts-ptv", "privileged"), ("ts-ptv", "multimodal"), ("ts-pt", "multimodal"),
                        ("pt", "multimodal")):
        r = [updates_per_s(policy.SAC(obs, tacrl.POSE_SCALE, sim.F_MAX6, threads=threads,
                                      state_dim=tacrl.STATE_DIM if critic == "privileged" else 0,
                                      extra_dim=0 if critic == "privileged" else tacrl.EXTRA_DIM),
                           buf, rng, a.batch, a.updates) for _ in range(a.repeats)]
        print(f"{obs:6s} critics {critic:10s}: median {np.median(r):5.1f} updates/s "
              f"(min {min(r):.1f}, max {max(r):.1f})")
    env = sim.AssemblyEnv("peg", e_r=sim.E_R_FINAL)
    sac = tacrl.make_sac(tacrl.Config(), "cpu")        # the default training configuration
    t_env, t_upd = [], []
    for k in range(a.repeats):
        obs, _ = env.reset(seed=k)
        t0, done, n = time.perf_counter(), False, 0
        while not done:
            obs, _, term, trunc, _ = env.step(sac.act(obs))
            done, n = term or trunc, n + 1
        t_env.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        for _ in range(200):
            sac.update(buf.sample(a.batch, rng))
        t_upd.append(time.perf_counter() - t0)
    env.close()
    print(f"training episode (peg, 20 mm, {n} steps): env {np.median(t_env):.1f} s + 200 updates "
          f"{np.median(t_upd):.1f} s = {np.median(t_env) + np.median(t_upd):.1f} s (medians of {a.repeats})")


if __name__ == "__main__":
    main()
