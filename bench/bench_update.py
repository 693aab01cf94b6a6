"""Where one SAC update's time goes, for the default training configuration (TA-MRP actor with its own
CNN + LSTM encoder, privileged critics, batch 64), and what the update costs with each speed-up.

    python bench/bench_update.py [--updates 100] [--repeats 5] [--threads 1,2]

1. The parts, each timed alone on the same batch (median of `repeats` runs of `updates` calls):
   replay sampling, numpy -> torch, the actor's encoder forward without gradient (the TD target's
   a' ~ pi(o')), its forward and backward with gradient (the actor loss), split into CNN and LSTM,
   the critics' and actor's MLPs forward and backward, the three Adam steps and the Polyak average.
   What the sum of the parts leaves of a whole update is Python and autograd bookkeeping.
2. Before and after the speed-ups that leave the learning as it is, as whole updates, timed in turns
   (ABAB...) on the same batches so that the machine's drift hits both alike: Adam with foreach=True
   (before) against fused=True (after, the default since issue 20).
The machine is shared and noisy: compare ratios from one run, not numbers across runs.
"""
import argparse
import os
import sys
import time

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import policy  # noqa: E402
import sim  # noqa: E402
import tacrl  # noqa: E402

SHAPES = {"image": (sim.IMG, sim.IMG), "pose_hist": (sim.HIST, 6), "wrench_hist": (sim.HIST, 6),
          "state": (policy.STATE_DIM,)}


def filled_buffer(rng, n=5000):
    buf = policy.ReplayBuffer(n, SHAPES)
    T = n // 10
    for _ in range(10):
        buf.add_episode({"obs": {"image": rng.integers(0, 256, (T + 1, sim.IMG, sim.IMG), dtype=np.uint8),
                                 "pose_hist": rng.normal(0, 0.01, (T + 1, sim.HIST, 6)).astype(np.float32),
                                 "wrench_hist": rng.normal(0, 1, (T + 1, sim.HIST, 6)).astype(np.float32),
                                 "state": rng.normal(0, 1, (T + 1, policy.STATE_DIM)).astype(np.float32)},
                         "act": rng.uniform(-1, 1, (T, 6)), "rew": rng.normal(size=T), "term": np.zeros(T)})
    return buf


def median_ms(fn, calls, repeats):
    fn()                                           # warm up (allocation, first-call costs)
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        runs.append((time.perf_counter() - t0) / calls * 1000)
    return float(np.median(runs))


def parts(sac, buf, rng, batch, calls, repeats):
    """{part: ms a call}, timed alone on one batch."""
    o, a, r, o2, term, _ = buf.sample(batch, rng)
    to_t = lambda d: {k: torch.as_tensor(v) for k, v in d.items()}   # noqa: E731
    ot = to_t(o)
    enc, actor, q = sac.actor_enc, sac.actor, sac.q
    img, series = ot["image"], torch.cat([ot["pose_hist"] / enc.pose_scale, ot["wrench_hist"] / enc.wrench_scale], 2)
    z = enc(ot).detach()
    za = torch.cat([sac.enc(ot), torch.as_tensor(a)], 1).detach()

    def backward_of(f, *inputs):
        def run():
            f(*inputs).sum().backward()
        return run
    with torch.no_grad():
        nograd = {"encoder forward, no grad (TD target's a')": lambda: enc(ot),
                  "  of which the CNN ": lambda: enc.image(img), "  of which the LSTM ": lambda: enc.series(series)}
        out = {"replay sample": lambda: buf.sample(batch, rng), "numpy -> torch": lambda: (to_t(o), to_t(o2))}
        out = {k: median_ms(f, calls, repeats) for k, f in out.items()}
        out.update({k: median_ms(f, calls, repeats) for k, f in nograd.items()})
    out["encoder forward + backward (actor loss)"] = median_ms(backward_of(enc, ot), calls, repeats)
    out["  of which the CNN"] = median_ms(backward_of(enc.image, img), calls, repeats)
    out["  of which the LSTM"] = median_ms(backward_of(enc.series, series), calls, repeats)
    out["twin Q MLPs forward + backward, x2"] = 2 * median_ms(backward_of(lambda x: sum(q.q1(x) + q.q2(x)), za),
                                                              calls, repeats)
    out["actor MLP forward + backward, x2"] = 2 * median_ms(backward_of(lambda x: actor(x)[0], z), calls, repeats)
    out["three Adam steps + Polyak"] = median_ms(lambda: (sac.q_opt.step(), sac.pi_opt.step(), sac.alpha_opt.step(),
                                                          torch._foreach_lerp_(sac._targ_params, sac._online_params,
                                                                               sac.tau)), calls, repeats)
    return out


def whole(make, buf, rng, batch, calls, repeats):
    sac = make()
    return median_ms(lambda: sac.update(buf.sample(batch, rng)), calls, repeats)


def foreach_adam(sac, lr):
    """The optimisers as they were before issue 20 (foreach=True, and a plain Adam for the temperature)."""
    sac.q_opt = torch.optim.Adam(sac._online_params, lr=lr, foreach=True)
    sac.pi_opt = torch.optim.Adam(list(sac.actor.parameters()) + list(sac.actor_enc.parameters()), lr=lr, foreach=True)
    sac.alpha_opt = torch.optim.Adam([sac.log_alpha], lr=lr)
    return sac


def in_turns(variants, batches, rounds):
    """{name: median ms an update}, the variants timed in turns over the same batches."""
    times = {name: [] for name in variants}
    for _ in range(rounds):
        for name, sac in variants.items():
            t0 = time.perf_counter()
            for b in batches:
                sac.update(b)
            times[name].append((time.perf_counter() - t0) / len(batches) * 1000)
    return {name: float(np.median(t)) for name, t in times.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--updates", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--threads", default="1,2")
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    buf = filled_buffer(rng)
    cfg = tacrl.Config()
    print(f"torch {torch.__version__}, batch {a.batch}, {a.repeats} x {a.updates} calls, medians in ms a call")
    for threads in map(int, a.threads.split(",")):
        torch.set_num_threads(threads)
        torch.manual_seed(0)
        sac = tacrl.make_sac(cfg, "cpu")
        full = whole(lambda: tacrl.make_sac(cfg, "cpu"), buf, rng, a.batch, a.updates, a.repeats)
        p = parts(sac, buf, rng, a.batch, a.updates, a.repeats)
        top = sum(v for k, v in p.items() if not k.startswith("  "))
        print(f"\n{threads} thread{'s' * (threads > 1)}: a whole update {full:6.2f} ms ({1000 / full:5.1f} updates/s)")
        for k, v in p.items():
            print(f"  {k:45s} {v:6.2f} ms  {v / full:5.1%}")
        print(f"  {'the rest: Python, autograd bookkeeping':45s} {full - top:6.2f} ms  {(full - top) / full:5.1%}")
        variants = {"before: Adam foreach": foreach_adam(tacrl.make_sac(cfg, "cpu"), cfg.lr),
                    "after: Adam fused": tacrl.make_sac(cfg, "cpu")}
        ms = in_turns(variants, [buf.sample(a.batch, rng) for _ in range(20)], a.repeats * 3)
        print("  " + "   ".join(f"{k} {v:6.2f} ms" for k, v in ms.items()) +
              f"   after / before: {ms['before: Adam foreach'] / ms['after: Adam fused']:.3f}x the updates/s")


if __name__ == "__main__":
    main()
