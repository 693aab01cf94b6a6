"""What each of Fig. 11's windows shows at the start of an episode: over errors drawn as Eq. 13 draws them at
5-20 mm, the share of episodes whose first image (the camera at X^_i, Eq. 14) holds the centre of the hole's rim or
the shaft's top, and the share that holds all of it. tests/test_sim.py checks the windows by Eq. 11's box (every task
feature at every error); this measures what a policy can see of the one feature that says where to go.

    python bench/roi_coverage.py [--draws 400]

Geometry only (no physics, no rendering): a few seconds.
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import control as ctl  # noqa: E402
import scene  # noqa: E402
import sim  # noqa: E402

LEVELS_MM = (5, 10, 15, 20)


def coverage(task, roi, draws, rng):
    """{E_r mm: (share with the feature's centre in the window, share with all of it)}."""
    with sim.AssemblyEnv(task, roi=roi, image=False) as env:
        env.reset(seed=0)
        w, R_b = env.world, env.x_g[1] @ sim.R_DOWN
        board = env.x_g[0] - R_b @ w.goal_in_board()
        rim = board + scene.task_features(task)[:16] @ R_b.T       # the hole's rim, or the shaft's top: 16 points
        u0, v0, u1, v1 = env.roi
        proj, out = scene.full_projection(), {}
        for mm in LEVELS_MM:
            scale = np.array([mm / 1000] * 3 + [sim.E_ROT_FINAL * mm / 1000 / sim.E_R_FINAL])
            centre, whole = [], []
            for e in rng.uniform(-1, 1, (draws, 4)) * scale:            # Eq. 13
                R_t = ctl.rot_z(e[3]) @ env.x_i[1]                      # Eq. 14: X^_i = X_i + e
                p_t = env.x_i[0] + R_b @ e[:3]
                uv = scene.project(rim, w.camera_matrices((p_t + R_t @ w.cam_rel[0], R_t @ w.cam_rel[1])), proj)
                inside = (uv[:, 0] >= u0) & (uv[:, 0] <= u1) & (uv[:, 1] >= v0) & (uv[:, 1] <= v1)
                c = uv.mean(0)
                centre.append(u0 <= c[0] <= u1 and v0 <= c[1] <= v1)
                whole.append(inside.all())
            out[mm] = (float(np.mean(centre)), float(np.mean(whole)))
        return out, env.roi


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--draws", type=int, default=400, help="errors drawn a level (default: 400)")
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    print("task  window   (u0, v0, u1, v1) px   share of first images with the feature's centre in view / all of it, "
          f"at {' / '.join(map(str, LEVELS_MM))} mm")
    for task in ("peg", "gear"):
        for roi in ("task", "300", "200", "100x160"):
            cov, box = coverage(task, roi, a.draws, rng)
            print(f"{task:5s} {roi:8s} ({', '.join(f'{x:.0f}' for x in box)})  " +
                  "  ".join(f"{mm} mm {c:.2f} / {w:.2f}" for mm, (c, w) in cov.items()))


if __name__ == "__main__":
    main()
