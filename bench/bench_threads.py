"""SAC updates/s of the default training configuration, alone and beside one other busy process, for the ways
of putting an update on 2 cores: what tacrl.py's default (one torch thread an op, policy.Helper's two halves of
each batch) is chosen from. Also the policy's actions/s (one observation at a time, as an episode acts).

    python bench/bench_threads.py [--updates 80] [--repeats 3]

Each cell runs in a fresh process, since OpenMP reads its settings once, when torch loads. "Busy" runs one
single-threaded busy loop beside it, as any other program on a user's machine would (a second training run, a
compiler). The table prints medians over `repeats` and two ratios: beside a busy process against alone
(OpenMP's threads wait for each other at every op, so torch's own default slowed 3-4x there), and alone
against torch's own default (2 OpenMP threads on 2 cores, the whole batch).
Run nothing else heavy beside it; compare ratios from one run, not figures across runs.
"""
import argparse
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# (name, torch threads an op, threads an update (policy.Helper), environment)
VARIANTS = [("torch's default: 2 OpenMP threads, the whole batch", 2, 0, {}),
            ("2 OpenMP threads, OMP_WAIT_POLICY=PASSIVE", 2, 0, {"OMP_WAIT_POLICY": "PASSIVE"}),
            ("tacrl's default: 1 an op, the halves on 2 threads", 1, 2, {}),
            ("1 thread, the halves one after the other", 1, 1, {})]
WAIT_VARS = ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT", "OMP_NUM_THREADS")


def worker(threads, helper, updates, acts=120):
    """In a fresh process: actions/s of the policy, then updates/s of the default configuration's SAC update with
    `threads` torch threads an op and, with helper > 0, the batch's halves on `helper` threads (0: the whole batch
    in one call, as before issue 49)."""
    sys.path.insert(0, ROOT)
    import torch
    from bench_sac import filled_buffer
    import command
    import tacrl
    torch.set_num_threads(threads)
    command.keep_freed_memory()
    rng = np.random.default_rng(0)
    buf, sac = filled_buffer(rng), tacrl.make_sac(tacrl.Config(threads=max(1, helper)), "cpu")
    if not helper:
        sac.encode = lambda enc, o: enc(o)
    o = {k: v[0] for k, v in buf.sample(1, rng)[0].items() if k in ("image", "pose_hist", "wrench_hist")}
    sac.act(o)
    t0 = time.perf_counter()
    for _ in range(acts):                                    # an episode's actions, one observation each
        sac.act(o)
    act_rate = acts / (time.perf_counter() - t0)
    for _ in range(5):
        sac.update(buf.sample(64, rng))
    t0 = time.perf_counter()
    for _ in range(updates):
        sac.update(buf.sample(64, rng))
    print(act_rate, updates / (time.perf_counter() - t0))


def cell(threads, helper, env, updates, busy):
    """(actions/s, updates/s) of one fresh worker process, beside a busy loop if `busy`."""
    env = {**{k: v for k, v in os.environ.items() if k not in WAIT_VARS}, **env}
    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
    try:
        out = subprocess.run([sys.executable, __file__, "--worker", f"{threads},{helper}", "--updates", str(updates)],
                             env=env, capture_output=True, text=True, check=True)
    finally:
        if hog:
            hog.kill()
            hog.wait()
    return tuple(float(x) for x in out.stdout.split()[-2:])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--updates", type=int, default=80)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker is not None:
        return worker(*map(int, a.worker.split(",")), a.updates)
    print(f"{os.cpu_count()} cores, {a.updates} updates a cell, medians of {a.repeats} (cells in turns)")
    runs = {(name, busy): [] for name, *_ in VARIANTS for busy in (False, True)}
    for _ in range(a.repeats):                       # in turns, so that the machine's drift hits every cell alike
        for name, threads, helper, env in VARIANTS:
            for busy in (False, True):
                runs[name, busy].append(cell(threads, helper, env, a.updates, busy))
    for col, unit in ((1, "updates/s"), (0, "actions/s right after start")):
        med = {k: float(np.median([r[col] for r in v])) for k, v in runs.items()}
        base = med[VARIANTS[0][0], False]
        print(f"\n{'variant':52s} {'alone':>8s} {'busy':>8s} {'slowdown':>9s} {'alone / default':>16s}  every run, "
              "alone | busy")
        for name, *_ in VARIANTS:
            alone, busy = med[name, False], med[name, True]
            every = " | ".join(" ".join(f"{r[col]:.0f}" for r in runs[name, b]) for b in (False, True))
            print(f"{name:52s} {alone:8.1f} {busy:8.1f} {alone / busy:8.2f}x {alone / base:15.0%}  {every}")
        print(f"({unit}; slowdown: alone / beside one busy process)")


if __name__ == "__main__":
    main()
