"""Ours beside what a user would pick instead: Stable-Baselines3's SAC on the same Gymnasium env
(tacrl/PegInsertion-v0: the same hybrid controller, residual action F_d, observations and reward), with
the same adaptive curriculum (Eq. 16) between episodes, for the same wall time.

    pip install stable-baselines3                # optional: never needed by tacrl, never in CI
    python bench/bench_sb3.py [--seed 0] [--threads 2] [--ours RUN_DIR]

1. Ours: `python tacrl.py --task peg --seed S` as the quickstart runs it (it stops when learned), in a
   new run dir under bench/runs/, or a finished run of it given with --ours (its metrics.csv and
   eval.json; then only SB3 trains).
2. SB3: SAC("MultiInputPolicy") with its defaults (batch 256, one update per env step, gamma 0.99, its
   CNN on the image, which the env gives as 1 x 80 x 80 uint8), the replay buffer ours has (50,000: its default million
   would not fit), trained for the wall time ours took.
Both then act deterministically at 20 mm on the same held-out seeds (tacrl.evaluate, seeds from
EVAL_SEED + S). For each it prints the minutes until its training curve first showed SR >= 0.9 at
20 mm (the curriculum at its final 20 mm range for 30 episodes, with a success rate over the last 15
of at least 0.9: one rule read off both logs) and the success rate at 20 mm.
Run it alone on the machine: the two trainings run one after the other, each on --threads threads.
"""
import argparse
import csv
import json
import os
import sys
import time

import gymnasium as gym
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import evaluate  # noqa: E402
import curriculum  # noqa: E402
import sim  # noqa: E402
import tacrl  # noqa: E402

HELD, SR = 30, 0.9            # "SR >= 0.9 at 20 mm" on a training curve: 30 episodes at 20 mm, sr15 >= 0.9


class SameTask(gym.Wrapper):
    """The curriculum of tacrl.py between episodes (Eq. 16 on the last 15 successes) and a log of (seconds, E_r,
    success, sr15) an episode."""

    def __init__(self, env):
        super().__init__(env)
        self.curr = curriculum.Curriculum("adaptive", final=sim.E_R_FINAL)
        self.ended, self.log, self.t0 = None, [], time.time()

    def reset(self, **kw):
        if self.ended is not None:                   # the episode that just ended
            e_r = self.env.unwrapped.e_r
            self.curr.update(self.ended)
            self.log.append((time.time() - self.t0, e_r, self.ended, self.curr.success_rate))
        self.env.unwrapped.set_ranges(*self.curr.ranges())
        self.ended = None
        return self.env.reset(**kw)

    def step(self, action):
        obs, r, term, trunc, info = self.env.step(action)
        if term or trunc:
            self.ended = bool(term)
        return obs, r, term, trunc, info


def minutes_to_criterion(episodes):
    """episodes: (elapsed s, E_r (m), success, sr15) each; the minutes when the final range had been held
    HELD episodes with sr15 >= SR, or None."""
    held = 0
    for t, e_r, _, sr15 in episodes:
        held = held + 1 if e_r >= sim.E_R_FINAL - 1e-9 else 0
        if held >= HELD and sr15 >= SR:
            return t / 60
    return None


def run_ours(seed, threads, root, run_dir=None):
    """Trains ours (or reads the finished run in run_dir): its minutes, episodes and row at 20 mm."""
    if run_dir is None:
        run_dir = os.path.join(root, f"ours-s{seed}")
        cfg = tacrl.parse_args(["--task", "peg", "--seed", str(seed), "--threads", str(threads), "--run-dir", run_dir])
        shown = ("stopped", "TA-MRP")
        tacrl.train(cfg, log=lambda msg: print("  ours:", msg, flush=True) if msg.startswith(shown) else None)
    with open(os.path.join(run_dir, "eval.json")) as f:
        result = json.load(f)
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        rows = list(csv.DictReader(f))
    episodes = [(float(r["elapsed_s"]), float(r["e_r_mm"]) / 1000, int(r["success"]), float(r["sr15"])) for r in rows]
    row20 = next(r for r in result["rows"] if r["error_mm"] == 20.0)
    return {"train_minutes": result["train_minutes"], "episodes": len(rows), "seed": result["seed"],
            "to_criterion": minutes_to_criterion(episodes), "sr20": row20["success_rate"],
            "ct20": row20["completion_time_s"]}


def run_sb3(seed, threads, seconds):
    from stable_baselines3 import SAC
    from stable_baselines3.common.callbacks import BaseCallback

    class Deadline(BaseCallback):
        def _on_step(self):
            return time.time() - t0 < seconds
    torch.set_num_threads(threads)
    env = SameTask(gym.make("tacrl/PegInsertion-v0"))
    model = SAC("MultiInputPolicy", env, buffer_size=50_000, seed=seed, verbose=0)
    t0 = env.t0 = time.time()
    model.learn(total_timesteps=10 ** 9, callback=Deadline())
    episodes = env.log
    e_r, ex_r = env.curr.ranges()
    env.close()
    act = lambda obs: model.predict(obs, deterministic=True)[0]   # noqa: E731
    with sim.AssemblyEnv("peg", e_r=sim.E_R_FINAL, ex_r=ex_r) as eval_env:   # its controller as training ended
        row = evaluate.evaluate(eval_env, act, 20, evaluate.EVAL_SEED + seed, log=lambda *_: None)
    return {"train_minutes": seconds / 60, "episodes": len(episodes), "final_e_r_mm": 1000 * max(
        (x[1] for x in episodes), default=0.0), "to_criterion": minutes_to_criterion(episodes),
        "sr20": row["success_rate"], "ct20": row["completion_time_s"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ours", help="a finished run dir of `python tacrl.py --task peg` to compare with")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "runs"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    print(f"ours (tacrl.py), seed {a.seed}, {a.threads} torch threads", flush=True)
    ours = run_ours(a.seed, a.threads, a.out, a.ours)
    if ours["seed"] != a.seed:
        sys.exit(f"--ours: {a.ours} was trained with seed {ours['seed']}, not --seed {a.seed}")
    print(f"SB3 SAC, seed {a.seed}, for the {ours['train_minutes']:.1f} min ours trained", flush=True)
    sb3 = run_sb3(a.seed, a.threads, ours["train_minutes"] * 60)
    for name, r in (("ours", ours), ("SB3 SAC", sb3)):
        crit = "not reached" if r["to_criterion"] is None else f"{r['to_criterion']:.1f} min"
        ct = "-" if r["ct20"] is None else f"{r['ct20'][0]:.2f} s"
        print(f"{name:8s} trained {r['train_minutes']:5.1f} min, {r['episodes']:4d} episodes; to the criterion "
              f"(20 mm held {HELD} episodes, SR over 15 >= {SR}): {crit}; SR at 20 mm (20 held-out episodes) "
              f"{r['sr20']:.2f}, CT {ct}")
    with open(os.path.join(a.out, f"sb3-vs-ours-s{a.seed}.json"), "w") as f:
        json.dump({"world": sim.WORLD, "seed": a.seed, "ours_run": a.ours, "ours": ours, "sb3": sb3}, f, indent=2)


if __name__ == "__main__":
    main()
