"""How much the arm's posture at another table place changes an episode (issue 22, point 1): the same
episode (seed, errors in the board's frame, sensors without noise, zero residual) at each place of the board;
the tip's path in the board's frame against the training place's, and how often a joint motor runs at its
torque cap. Usage: python bench/arm_posture.py [--task peg] [--error-mm 10]"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import sim  # noqa: E402


def episode(task, ctx, error, seed=3):
    """Tip positions in the board frame (steps, 3), m; fraction of ticks with any joint at its cap; success."""
    with sim.AssemblyEnv(task, ctx, e_r=0.02, image=False, ft_noise=False, image_noise=False) as env:
        env.reset(seed=seed, options={"error": error})
        w, R_b = env.world, env.x_g[1] @ sim.R_DOWN
        path, capped, ticks, done = [], 0, 0, False
        real_tick = w.tick

        def tick(*a):                      # count the ticks where a motor gives all it has
            nonlocal capped, ticks
            out = real_tick(*a)
            tau = np.array([s[3] for s in w.bc.getJointStates(w.robot, w.arm)])
            capped += bool(np.any(np.abs(tau) >= 0.999 * np.array(w.max_force)))
            ticks += 1
            return out
        w.tick = tick
        while not done:
            _, _, term, trunc, info = env.step(np.zeros(6))
            path.append(R_b.T @ (w.tool_pose()[0] - env.x_g[0]))
            done = term or trunc
    return np.array(path), capped / max(ticks, 1), term


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--task", default="peg", choices=["peg", "gear"])
    ap.add_argument("--error-mm", type=float, default=10.0)
    a = ap.parse_args()
    e = a.error_mm / 1000
    for error in (np.array([e, -e, 0.0, 0.05]), np.array([-e, 0.0, e / 2, -0.05])):
        ref, cap0, ok0 = episode(a.task, "train", error)
        print(f"error {np.round(error * [1000, 1000, 1000, 1], 3)}: train {len(ref)} steps, success {ok0}, "
              f"ticks at a torque cap {cap0:.1%}")
        for ctx in [c for c in sim.CONTEXTS if c.startswith("loc-")]:
            path, cap, ok = episode(a.task, ctx, error)
            n = min(len(path), len(ref))
            dev = np.linalg.norm(path[:n] - ref[:n], axis=1)
            print(f"  {ctx}: {len(path)} steps, success {ok}, tip path from train's: max {dev.max() * 1000:.2f} mm, "
                  f"median {np.median(dev) * 1000:.2f} mm; ticks at a torque cap {cap:.1%}")
