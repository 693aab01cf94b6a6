"""SAC updates/s of the default training configuration for torch thread counts and OpenMP wait policies,
alone and beside one other busy process: what tacrl.py's default (cli.CoreShare) is chosen from. Also the
policy's actions/s right after start (one observation at a time, as an episode acts), on the threads the
variant starts with: where a run's first episode acts.

    python bench/bench_threads.py [--updates 80] [--repeats 3]

Each cell runs in a fresh process, since OpenMP reads OMP_WAIT_POLICY and GOMP_SPINCOUNT once, when torch
loads. "Busy" runs one single-threaded busy loop beside it, as any other program on a user's machine
would (a second training run, a browser tab, a compiler). The table prints medians over `repeats` and two
ratios: beside a busy process against alone (the issue's bar: at most 2x slower), and alone against
torch's own default (2 threads on 2 cores, OpenMP's default wait; the bar: at least 85 %).
Run nothing else heavy beside it; compare ratios from one run, not figures across runs.
"""
import argparse
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# (name, torch threads, environment); the threads' wait: libgomp spins 300,000 times by default before it
# sleeps, forever with ACTIVE, not at all with PASSIVE (gcc.gnu.org/onlinedocs/libgomp, GOMP_SPINCOUNT)
VARIANTS = [("2 threads, OpenMP default wait (torch's default)", 2, {}),
            ("2 threads, OMP_WAIT_POLICY=ACTIVE", 2, {"OMP_WAIT_POLICY": "ACTIVE"}),
            ("2 threads, OMP_WAIT_POLICY=PASSIVE", 2, {"OMP_WAIT_POLICY": "PASSIVE"}),
            ("2 threads, GOMP_SPINCOUNT=10000", 2, {"GOMP_SPINCOUNT": "10000"}),
            ("tacrl's default: a thread a free core (tacrl.CoreShare)", 0, {}),
            ("1 thread", 1, {}),
            ("1 thread, OMP_WAIT_POLICY=PASSIVE", 1, {"OMP_WAIT_POLICY": "PASSIVE"})]
WAIT_VARS = ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT", "OMP_NUM_THREADS")


def worker(threads, updates, acts=120):
    """In a fresh process: actions/s of the policy right after start, then updates/s of the default
    configuration's SAC update, with `threads` torch threads (0: as tacrl.py's default, a thread a core that
    other processes leave free, decided at start and re-decided every 20 updates)."""
    sys.path.insert(0, ROOT)
    import torch
    from bench_sac import filled_buffer
    import tacrl
    share = tacrl.CoreShare(threads)
    torch.set_num_threads(share.free())
    rng = np.random.default_rng(0)
    buf, sac = filled_buffer(rng), tacrl.make_sac(tacrl.Config(), "cpu")
    o = {k: v[0] for k, v in buf.sample(1, rng)[0].items() if k in ("image", "pose_hist", "wrench_hist")}
    sac.act(o)
    t0 = time.perf_counter()
    for _ in range(acts):                                    # an episode's actions, one observation each
        sac.act(o)
    act_rate = acts / (time.perf_counter() - t0)
    for _ in range(5):
        sac.update(buf.sample(64, rng))
    t0 = time.perf_counter()
    for _ in share.steps(updates, torch.set_num_threads):
        sac.update(buf.sample(64, rng))
    print(act_rate, updates / (time.perf_counter() - t0))


def cell(threads, env, updates, busy):
    """(actions/s, updates/s) of one fresh worker process, beside a busy loop if `busy`."""
    env = {**{k: v for k, v in os.environ.items() if k not in WAIT_VARS}, **env}
    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
    try:
        out = subprocess.run([sys.executable, __file__, "--worker", str(threads), "--updates", str(updates)],
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
    ap.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker is not None:
        return worker(a.worker, a.updates)
    print(f"{os.cpu_count()} cores, {a.updates} updates a cell, medians of {a.repeats} (cells in turns)")
    runs = {(name, busy): [] for name, _, _ in VARIANTS for busy in (False, True)}
    for _ in range(a.repeats):                       # in turns, so that the machine's drift hits every cell alike
        for name, threads, env in VARIANTS:
            for busy in (False, True):
                runs[name, busy].append(cell(threads, env, a.updates, busy))
    for col, unit in ((1, "updates/s"), (0, "actions/s right after start")):
        med = {k: float(np.median([r[col] for r in v])) for k, v in runs.items()}
        base = med[VARIANTS[0][0], False]
        print(f"\n{'variant':52s} {'alone':>8s} {'busy':>8s} {'slowdown':>9s} {'alone / default':>16s}  every run, alone | busy")
        for name, _, _ in VARIANTS:
            alone, busy = med[name, False], med[name, True]
            every = " | ".join(" ".join(f"{r[col]:.0f}" for r in runs[name, b]) for b in (False, True))
            print(f"{name:52s} {alone:8.1f} {busy:8.1f} {alone / busy:8.2f}x {alone / base:15.0%}  {every}")
        print(f"({unit}; slowdown: alone / beside one busy process; the bar: <= 2x, and alone >= 85 % of the default)")


if __name__ == "__main__":
    main()
