"""Where one SAC update's time goes: for the default configuration (privileged critics: the actor's CNN + LSTM
encoder is the only multimodal one) and for the paper's critics (--critic multimodal: their encoder, which the
actor reads, and its Polyak target), on 1 and 2 threads (policy.Helper: each multimodal encoder's batch as two
halves, the second on a helper thread; the numbers are the same either way).

    python bench/bench_update.py [--updates 60] [--repeats 5] [--batch 64]

Each part is timed alone, as the update runs it (in halves, on the given threads), on one batch: median of
`repeats` runs of `updates` calls, in ms a call and as a share of the whole update (timed the same way):
    each multimodal encoder's forward without gradient (the TD target's o'), and forward + backward (the loss
    that trains it), split into its CNN and its LSTM; the twin Q heads' forward + backward (the critic loss;
    again on the actor's action); the actor's MLP forward + backward; the optimisers' steps and the Polyak
    average. What the parts leave of the whole is Python, autograd and the small ops between them.
The machine is shared and noisy: compare shares and ratios from one run. bench/bench_sac.py gives updates/s.
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
import tacrl  # noqa: E402
from bench_sac import filled_buffer  # noqa: E402


def median_ms(fn, calls, repeats):
    fn()                                           # the first call allocates
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        runs.append((time.perf_counter() - t0) / calls * 1000)
    return float(np.median(runs))


def grads(f, params):
    """A call: f() -> a tensor, and its backward to params (as the update's losses do, per half)."""
    return lambda: torch.autograd.grad(f().sum(), params, allow_unused=True)


def parts(sac, o, a, calls, repeats):
    """{part: ms a call} of one update of `sac` on the batch (o, a)."""
    ms = lambda f: median_ms(f, calls, repeats)                        # noqa: E731
    encoders = {"actor's encoder": sac.actor_enc} if sac.shared else {"actor's encoder": sac.actor_enc,
                                                                       "critics' encoder": sac.enc}
    out = {}
    for name, enc in encoders.items():
        if not isinstance(enc, policy.Encoder):
            continue
        params = [p for p in enc.parameters() if p.requires_grad]
        with torch.no_grad():
            out[f"{name}: forward of o', no gradient (the TD target)"] = ms(lambda: sac.encode(enc, o))
        out[f"{name}: forward + backward (o)"] = ms(grads(lambda: sac.encode(enc, o), params))
        inputs = [("CNN", enc.image, o["image"])] if enc.image is not None else []
        if hasattr(enc, "series"):                 # the LSTM reads both series side by side, as Encoder.forward
            inputs.append(("LSTM", enc.series, torch.cat([o["pose_hist"] / enc.pose_scale,
                                                          o["wrench_hist"] / enc.wrench_scale], 2)))
        for part, m, x in inputs:
            ps = list(m.parameters())
            out[f"  of which the {part}"] = ms(grads(lambda: policy.in_halves(lambda d: m(d["x"]), ps, {"x": x},
                                                                               sac.helper), ps))
    with torch.no_grad():
        z = sac.actor_enc(o)
        za = torch.cat([sac.critic_input(sac.enc(o), o), a], 1)
    q = list(sac.q.parameters())
    out["twin Q heads: forward + backward, x2 (critic loss, actor loss)"] = 2 * ms(
        grads(lambda: sac.q.q1(za) + sac.q.q2(za), q))
    pi = list(sac.actor.parameters())
    out["actor's MLP: forward + backward, x2 (a' and the actor loss)"] = 2 * ms(grads(lambda: sac.actor(z)[1], pi))
    out["three Adam steps + Polyak"] = ms(lambda: (sac.q_opt.step(), sac.pi_opt.step(), sac.alpha_opt.step(),
                                                   torch._foreach_lerp_(list(sac.q_targ.parameters()), q, policy.TAU)))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--updates", type=int, default=60)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--batch", type=int, default=64)
    a = ap.parse_args()
    command.use_cpu()          # as a run: one thread an op, malloc keeping what it frees
    rng = np.random.default_rng(0)
    buf = filled_buffer(rng)
    print(f"torch {torch.__version__}, batch {a.batch}, {a.repeats} x {a.updates} calls, medians in ms a call")
    for critic in ("privileged", "multimodal"):
        for threads in (1, 2):
            torch.manual_seed(0)
            sac = tacrl.make_sac(tacrl.Config(critic=critic, threads=threads), "cpu")
            batches = [buf.sample(a.batch, rng) for _ in range(a.updates)]
            it = iter(batches * (a.repeats + 1) * 2)
            whole = median_ms(lambda: sac.update(next(it)), a.updates, a.repeats)
            o, act = ({k: torch.as_tensor(v) for k, v in batches[0][0].items()}, torch.as_tensor(batches[0][1]))
            p = parts(sac, o, act, a.updates, a.repeats)
            top = sum(v for k, v in p.items() if not k.startswith("  "))
            print(f"\ncritics {critic}, {threads} thread{'s' * (threads > 1)}: a whole update {whole:6.2f} ms "
                  f"({1000 / whole:5.1f} updates/s)")
            for k, v in p.items():
                print(f"  {k:66s} {v:6.2f} ms  {v / whole:5.1%}")
            print(f"  {'the rest: Python, autograd, small ops':66s} {whole - top:6.2f} ms  "
                  f"{(whole - top) / whole:5.1%}")


if __name__ == "__main__":
    main()
