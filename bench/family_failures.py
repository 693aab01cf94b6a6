"""Which scenes of a family does a policy fail? One episode in each of `scenes` held-out scenes.

    python bench/family_failures.py POLICY.pt [POLICY.pt ...] [--family colour] [--scenes 30] [--error-mm 20]

For each held-out seed (scene.FAMILY_TEST_SEED0 + k), one episode at E_r = error_mm in that family's scene
(--context FAMILY:SEED), and what the camera sees at its start: the task-attention image's mean grey level and
its spread (std), and, for colour scenes, the table's and the board's HSV value. Prints a line a scene, then
the success rate of the darker and the brighter half of the scenes by the image's mean, and of the flatter and
the more contrasted half by its spread.
"""
import argparse
import colorsys
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import evaluate  # noqa: E402
import scene  # noqa: E402
import sim  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("policies", nargs="+")
    ap.add_argument("--family", default="colour", choices=scene.FAMILIES)
    ap.add_argument("--scenes", type=int, default=30)
    ap.add_argument("--error-mm", type=float, default=20.0)
    a = ap.parse_args()
    rows = []                                   # (image mean, image std, success) a scene
    for path in a.policies:
        act = evaluate.load_policy(path)
        for k in range(a.scenes):
            seed = scene.FAMILY_TEST_SEED0 + k
            env = evaluate.eval_env(act.meta["task"], act, f"{a.family}:{seed}", e_r_mm=a.error_mm)
            first = []                          # the episode's first image, as the policy reads it

            def act_seeing(obs):
                if not first:
                    first.append(obs["image"] / 255.0)
                return act(obs)
            success, _, _ = sim.run_episode(env, act_seeing, seed=k)
            env.close()
            img = first[0]
            ctx = scene.family_context(a.family, seed, act.meta["task"])
            values = "".join(f"  {name} value {colorsys.rgb_to_hsv(*rgba[:3])[2]:.2f}"
                             for name, rgba in (("table", ctx.table_rgba), ("board", ctx.board_rgba)))
            rows.append((img.mean(), img.std(), bool(success)))
            print(f"{os.path.basename(os.path.dirname(path))}  {a.family}:{seed}  image mean {img.mean():.2f} std "
                  f"{img.std():.3f}{values if a.family in ('colour', 'mixed') else ''}  success {int(success)}", flush=True)
    r = np.array(rows, float)
    for col, name, halves in ((0, "mean", ("darker", "brighter")), (1, "std", ("flatter", "more contrasted"))):
        cut = np.median(r[:, col])
        lo, hi = r[r[:, col] <= cut, 2], r[r[:, col] > cut, 2]
        print(f"by the image's {name} (median {cut:.3f}): {halves[0]} half SR {lo.mean():.2f} ({len(lo)}), "
              f"{halves[1]} half SR {hi.mean():.2f} ({len(hi)})")


if __name__ == "__main__":
    main()
