"""Does exploration noise jam the peg? The hand-designed policy (F_d = 0) at 0 mm error, plus
Gaussian lateral noise (std of the action range, tanh-squashed) on F_d; prints how many episodes
insert and where the failed ones stopped. Measures the README's "exploration noise jams the peg".

    python bench/jam_noise.py --clearance-mm 0.1 --ex-r-mm 20 --std 0.05
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import sim  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--clearance-mm", type=float, default=0.1)
ap.add_argument("--ex-r-mm", type=float, default=2.0, help="exploration range Ex_r: sets the lateral stiffness")
ap.add_argument("--std", type=float, default=0.2, help="std of the lateral noise, in units of the action range")
ap.add_argument("--episodes", type=int, default=8)
a = ap.parse_args()
env = sim.AssemblyEnv("peg", e_r=0.0, clearance=a.clearance_mm / 1000)
env.set_ranges(0.0, a.ex_r_mm / 1000)
rng = np.random.default_rng(0)
ok, depths = 0, []
for ep in range(a.episodes):
    term, info, _ = sim.run_episode(env, lambda obs: np.r_[np.tanh(rng.normal(0, a.std, 2)), np.zeros(4)], seed=ep)
    ok += term
    depths.append(round(info["depth"] * 1000, 1))
env.close()
print(f"clearance {a.clearance_mm:.2f} mm, Ex_r {a.ex_r_mm:g} mm, lateral noise std {a.std}: "
      f"{ok}/{a.episodes} inserted; final depth (mm) {depths}")
