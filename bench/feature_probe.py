"""Do an encoder's features say where the hole is? A linear probe of a run's critic and actor encoders.

    python bench/feature_probe.py RUN_DIR [RUN_DIR ...] [--episodes 300] [--error-mm 20]

For each run (a run dir with its ckpt.pt): reset the env `episodes` times at E_r = error_mm on held-out
seeds, take the first observation and the true lateral offset of the tip from the goal (X - X_g in x
and y, the error the policy must undo; what Eq. 17's reward measures), encode the observation with the
critics' encoder and the actor's, and fit a ridge regression from the features (18-d, plus a constant)
to the offset on half of the episodes. Prints R^2 on the other half, per axis: 1 when the features hold
the offset linearly, 0 when they say nothing of it. A privileged critic has no image encoder (its line
says so); the actor's encoder then learned from the actor loss alone.
"""
import argparse
import os
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import policy  # noqa: E402
import sim  # noqa: E402
import tacrl  # noqa: E402


def r2(feats, y, ridge=1e-3):
    """Held-out R^2 per column of y of a ridge fit on the first half."""
    X = np.hstack([feats, np.ones((len(feats), 1))])
    h = len(X) // 2
    w = np.linalg.solve(X[:h].T @ X[:h] + ridge * np.eye(X.shape[1]), X[:h].T @ y[:h])
    err = y[h:] - X[h:] @ w
    return 1 - (err ** 2).sum(0) / ((y[h:] - y[h:].mean(0)) ** 2).sum(0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--episodes", type=int, default=300)
    ap.add_argument("--error-mm", type=float, default=20.0)
    a = ap.parse_args()
    torch.set_num_threads(1)
    for run in a.runs:
        cfg = tacrl.read_config(run)
        sac = tacrl.make_sac(cfg, "cpu")
        sac.load_state_dict(policy.load_file(os.path.join(run, "ckpt.pt"))["sac"])
        obs, offsets = [], []
        with sim.AssemblyEnv(cfg.task, e_r=a.error_mm / 1000) as env:
            for k in range(a.episodes):
                o, info = env.reset(seed=5000 + k)            # apart from training's, evaluation's, validation's
                obs.append(o)
                offsets.append(info["goal_offset"][:2] * 1000)   # mm
        batch = {k: torch.as_tensor(np.stack([o[k] for o in obs])) for k in obs[0]}
        y = np.array(offsets)
        with torch.no_grad():
            out = [f"{os.path.basename(os.path.normpath(run))}:"]
            for name, enc in (("critics", sac.enc), ("actor", sac.actor_enc)):
                if isinstance(enc, policy.StateEncoder):
                    out.append(f"{name}: privileged (no image)")
                    continue
                fx, fy = r2(enc(batch).numpy(), y)
                out.append(f"{name} R^2 x {fx:.2f} y {fy:.2f}")
        print("  ".join(out), flush=True)


if __name__ == "__main__":
    main()
