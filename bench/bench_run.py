"""A short default training run, timed for this checkout and for a base commit in turns, in one invocation:

    python bench/bench_run.py [--base f17a2a8] [--rounds 2] [-- extra tacrl.py flags, e.g. --threads 1]

The run: `python tacrl.py --task peg --train-episodes 12 --warmup 2 --stop-held 0 --episodes 1 --eval-levels 20`
(12 episodes, 200 updates each from the third, one evaluation episode), in a new run dir each time. The base
commit is checked out into a git worktree beside this repository's (git worktree add --detach) and kept for the
next call. Prints each run's wall time and its training minutes (metrics.csv's elapsed), the medians and the
ratios base / this: episodes a minute relative to the base. Run it alone on the machine: the runs take both cores.
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RUN = ["--task", "peg", "--train-episodes", "12", "--warmup", "2", "--stop-held", "0", "--episodes", "1",
       "--eval-levels", "20"]


def checkout(base):
    """A worktree of `base` (a commit), made once: <repo>/../tacrl-<commit>."""
    commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", base], capture_output=True, text=True,
                            check=True).stdout.strip()
    path = os.path.join(os.path.dirname(ROOT), f"tacrl-{commit}")
    if not os.path.isdir(path):
        subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", path, commit], check=True,
                       capture_output=True)
    return path, commit


def timed_run(tree, flags, run_dir):
    """(wall s, training s, update phases s, env s, env steps) of the short run in `tree`: its episodes differ
    where its numbers do (a failed episode runs 120 steps), so the update phases are compared apart."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, os.path.join(tree, "tacrl.py"), *RUN, *flags, "--run-dir", run_dir], cwd=tree,
                   check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        rows = list(csv.DictReader(f))
    return (wall, float(rows[-1]["elapsed_s"]),
            *(sum(float(r[k]) for r in rows) for k in ("update_s", "env_s", "steps")))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--base", default="f17a2a8", help="the commit to compare with (default: f17a2a8, before issue 49)")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("flags", nargs="*", help="extra tacrl.py flags for this checkout's runs (after --)")
    a = ap.parse_args()
    base, commit = checkout(a.base)
    trees = {f"base {commit}": (base, []), "this checkout": (ROOT, a.flags)}
    times = {k: [] for k in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.rounds):
            for k, (tree, flags) in trees.items():       # in turns, so that the machine's drift hits both alike
                times[k].append(timed_run(tree, flags, os.path.join(tmp, f"{r}-{k.split()[0]}")))
                w, t, u, e, n = times[k][-1]
                print(f"round {r + 1}, {k:15s} wall {w:6.1f} s, training {t:6.1f} s: update phases {u:5.1f} s, "
                      f"env {e:5.1f} s ({n:.0f} steps)", flush=True)
    med = {k: np.median(np.array(v), axis=0) for k, v in times.items()}
    (bw, bt, bu, _, _), (tw, tt, tu, _, _) = med[f"base {commit}"], med["this checkout"]
    print(f"medians of {a.rounds}: base {commit} {bw:.1f} s wall ({bt:.1f} s training, {bu:.1f} s updating), this "
          f"checkout {' '.join(a.flags)} {tw:.1f} s wall ({tt:.1f} s training, {tu:.1f} s updating): {bw / tw:.2f}x "
          f"the base's speed, {bt / tt:.2f}x its training episodes a minute, {bu / tu:.2f}x its updates/s")


if __name__ == "__main__":
    main()
