"""How far off may the tip be and still drop in? The hand-designed policy (F_d = 0) with a lateral
error of fixed size in X^_g (6 directions), at a given exploration range Ex_r; prints how many of
the episodes insert at each size. Measures the README's "the chamfer catches a tip within 0.7 mm".

    python bench/capture.py --ex-r-mm 20
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import sim  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--ex-r-mm", type=float, default=20.0, help="exploration range Ex_r: sets the lateral stiffness")
ap.add_argument("--errors-mm", default="0.3,0.5,0.7,1.0,1.5", help="lateral error sizes, comma-separated")
ap.add_argument("--directions", type=int, default=6)
a = ap.parse_args()
env = sim.AssemblyEnv("peg", e_r=0.0, image=False)
env.set_ranges(0.0, a.ex_r_mm / 1000)
for r_mm in map(float, a.errors_mm.split(",")):
    ok = 0
    for k in range(a.directions):
        ang = 2 * np.pi * k / a.directions + 0.3
        e = np.array([np.cos(ang), np.sin(ang), 0.0, 0.0]) * r_mm / 1000
        ok += sim.run_episode(env, lambda obs: np.zeros(6), seed=k, options={"error": e})[0]
    print(f"Ex_r {a.ex_r_mm:g} mm, lateral error {r_mm:g} mm: {ok}/{a.directions} inserted", flush=True)
env.close()
