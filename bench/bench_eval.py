"""Wall seconds of an evaluation on one core and on two (evaluate.Worker: a second process plays every other
episode), timed in turns, with the rows compared.

    python bench/bench_eval.py POLICY.pt [--episodes 20] [--repeats 3] [--error-mm 20]

Each repeat evaluates the policy on the same held-out episodes alone, then with the worker (started before the
clock, as training starts it at its first episode); prints each median, their ratio, and whether the rows are
equal (they must be: an episode depends on its seed only). Run it with the machine to itself.
"""
import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import command  # noqa: E402
import evaluate  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("policy", help="a policy.pt")
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--error-mm", type=float, default=20.0)
    a = ap.parse_args()
    command.use_cpu("cpu")
    pi = evaluate.load_policy(a.policy)
    times, rows = {"one core": [], "two (worker)": []}, {}
    with evaluate.eval_env(pi.meta["task"], pi, roi=pi.meta["roi"], e_r_mm=a.error_mm) as env, \
            evaluate.Worker() as worker:
        env.set_ranges(a.error_mm / 1000, pi.meta["ex_r"])
        for _ in range(a.repeats):
            for name, w in (("one core", None), ("two (worker)", worker)):
                t0 = time.perf_counter()
                rows[name] = evaluate.evaluate(env, pi, a.episodes, evaluate.EVAL_SEED, log=lambda *_: None, worker=w)
                times[name].append(time.perf_counter() - t0)
    med = {k: float(np.median(v)) for k, v in times.items()}
    for k, v in times.items():
        print(f"{k:14s} median {med[k]:6.2f} s  ({', '.join(f'{x:.2f}' for x in v)})  SR {rows[k]['success_rate']:.2f}")
    print(f"ratio one / two: {med['one core'] / med['two (worker)']:.2f}x; rows equal: "
          f"{rows['one core'] == rows['two (worker)']}")


if __name__ == "__main__":
    main()
