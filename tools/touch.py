"""touch.py: which part of the touch family a policy loses in (issue 53): the same held-out episodes at 20 mm in
scenes that each change one thing the part touches to an end of the family's range, the rest as in training;
or (--held-out) the family's held-out episodes one by one, each scene's friction, clearance and tilt beside its
outcome, at any error (0 mm: the pose known, so what is lost is lost in contact), for a run or for the
hand-designed part alone (`initial`); --family F lists another family's episodes so (colour: the board's and the
table's grey level beside each).

    python tools/touch.py results/contexts/peg-task-s0 --episodes 20      # -> one line a scene, and touch.json
    python tools/touch.py RUN --held-out --error-mm 0              # -> one line an episode, touch-heldout-0mm.json
    python tools/touch.py initial --held-out --error-mm 0 --task peg   # the hand-designed part (prints only)
    python tools/touch.py RUN --held-out --family colour          # -> colour-heldout-20mm.json
    python tools/touch.py RUN --held-out --family colour --views docs   # and docs/TASK-colour-heldout-views.png
"""
import json
import os
import signal
import sys

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\ntouch: interrupted\n"), os._exit(130)))

import numpy as np  # noqa: E402
import torch  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the core modules, one folder up
import baselines  # noqa: E402
import cli  # noqa: E402
import command  # noqa: E402
import contexts  # noqa: E402
import evaluate  # noqa: E402
import figures  # noqa: E402
import policy  # noqa: E402
import runs  # noqa: E402
import scene  # noqa: E402
import sim  # noqa: E402
from cli import ArgError  # noqa: E402

T = np.radians(1.0)
SCENES = {"training": scene.Context(),
          "oiled (0.10)": scene.Context(friction=contexts.TOUCH_FRICTION[0]),
          "dry (0.70)": scene.Context(friction=contexts.TOUCH_FRICTION[1]),
          "0.05 mm clearance": scene.Context(clearance=contexts.TOUCH_CLEARANCE[0]),
          "0.3 mm clearance": scene.Context(clearance=contexts.TOUCH_CLEARANCE[1]),
          "tilted 1 deg about x": scene.Context(tilt=(T, 0.0)),
          "tilted 1 deg about y": scene.Context(tilt=(0.0, T))}


def grey(rgba):
    """An rgba's luma, 0-1: what the gray camera (scene.LUMA) makes of it under white light."""
    return float(np.dot(rgba[:3], scene.LUMA))


def held_out(a):
    """--held-out: FAMILY:test's episodes one by one (the seeds of evaluation's, EVAL_SEED + the run's seed)."""
    if a.run == "initial":
        task, roi, seed, pi = a.task, "task", 0, None
    else:
        run = runs.load_run(a.run)
        task, roi, seed, pi = run["cfg"]["task"], run["cfg"]["roi"], run["cfg"]["seed"], runs.load_policy(run)
        if a.error_mm > pi.meta["e_r_max"] * 1000 + 1e-6:
            raise ArgError(f"--error-mm {a.error_mm:g}: this policy's view covers {pi.meta['e_r_max'] * 1000:g} mm")
    rows = []
    with evaluate.eval_env(task, pi, f"{a.family}:test", roi, e_r_mm=a.error_mm) as env:
        act = pi or baselines.make("initial", env)
        for k in range(a.episodes):
            term, info, _ = sim.run_episode(env, act, seed=evaluate.episode_seed(evaluate.EVAL_SEED + seed, k))
            c = env.scene
            if a.family == "touch":
                seen = {"friction": c.friction, "clearance_mm": c.clearance * 1000,
                        "tilt_deg": [float(np.degrees(t)) for t in c.tilt]}
                what = (f"friction {c.friction:.2f}  clearance {c.clearance * 1000:.3f} mm  tilt "
                        f"{np.degrees(c.tilt[0]):+.2f} / {np.degrees(c.tilt[1]):+.2f} deg (x / y)")
            else:
                seen = {"board_grey": grey(c.board_rgba), "table_grey": grey(c.table_rgba), "objects": len(c.objects)}
                what = "  ".join(f"{k.replace('_', ' ')} {v:.2f}" if isinstance(v, float) else f"{k} {v}"
                                 for k, v in seen.items())
            rows.append({"success": bool(term), **seen, "depth_mm": info["depth"] * 1000})
            print(f"episode {k + 1:2d}  {'inserted' if term else 'failed  '}  {what}  depth "
                  f"{info['depth'] * 1000:5.1f} mm", flush=True)
    sr = np.mean([r["success"] for r in rows])
    print(f"{a.run}: SR {sr:.2f} at {a.error_mm:g} mm in {a.family}:test ({a.episodes} episodes)")
    if pi is not None:
        cli.check_dir_writable(a.run, "the run dir")
        with open(os.path.join(a.run, f"{a.family}-heldout-{a.error_mm:g}mm.json"), "w") as f:
            json.dump({"world": sim.WORLD, "error_mm": a.error_mm, "sr": float(sr), "episodes": rows}, f, indent=1)
    if a.views:
        views(a, task, roi, seed, pi, rows)


def views(a, task, roi, seed, pi, rows, n=10):
    """--views DIR: the first image of the first n episodes as the camera gives it and as each of policy.IMAGE_NORMS
    hands it to the CNN, each episode's outcome above it -> DIR/{task}-{family}-heldout-views.png."""
    imgs = []
    with evaluate.eval_env(task, pi, f"{a.family}:test", roi, e_r_mm=a.error_mm) as env:
        for k in range(min(n, len(rows))):       # the same seed, so the same scene, pose and noise as the episode's
            imgs.append(env.reset(seed=evaluate.episode_seed(evaluate.EVAL_SEED + seed, k))[0]["image"])
    x = torch.as_tensor(np.stack(imgs))                                     # (n, 1, 80, 80) uint8
    shown = {"camera": x[:, 0].numpy().astype(np.float32)}
    shown.update({f"--image-norm {m}": policy.pixels(x, m)[:, 0].numpy() for m in policy.IMAGE_NORMS if m != "fixed"})
    titles = [f"{'in' if r['success'] else 'FAILED'}" + (f", board {r['board_grey']:.2f}" if "board_grey" in r else "")
              for r in rows[:len(imgs)]]
    cli.check_dir_writable(a.views, "--views")
    out = os.path.join(a.views, f"{task}-{a.family}-heldout-views.png")
    figures.plot_inputs(shown, titles, out, f"{task}, {a.family}:test at {a.error_mm:g} mm ({a.run}): the first image "
                                            "of each episode as the CNN reads it")
    print(f"wrote {out}")


def main(argv=None):
    ap = cli.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", help="a run directory with policy.pt (or, with --held-out, initial)")
    ap.add_argument("--episodes", type=int, default=20, help="held-out episodes a scene (default: 20)")
    ap.add_argument("--held-out", action="store_true", help="touch:test's episodes one by one, each scene beside it")
    ap.add_argument("--error-mm", type=float, help="with --held-out: the error range E_r (default: 20)")
    ap.add_argument("--family", choices=contexts.FAMILIES, help="with --held-out: the family (default: touch)")
    ap.add_argument("--task", choices=("peg", "gear"), help="with initial: the task (default: peg)")
    ap.add_argument("--views", metavar="DIR", help="with --held-out and a run: also draw the first 10 episodes' "
                                                 "images as each image norm reads them into DIR")
    a = ap.parse_args(argv)
    if a.episodes < 1:
        raise ArgError(f"--episodes must be at least 1, not {a.episodes}")
    if not a.held_out and (a.error_mm is not None or a.task is not None or a.family is not None or a.views):
        raise ArgError("--error-mm, --task, --family and --views are for --held-out: they would change nothing here")
    if a.views and a.run == "initial":
        raise ArgError("--views draws what a run's encoder reads: initial has none")
    if a.task is not None and a.run != "initial":
        raise ArgError("--task is for initial: a run's policy has its own")
    a.error_mm, a.task, a.family = 20.0 if a.error_mm is None else a.error_mm, a.task or "peg", a.family or "touch"
    if not 0 <= a.error_mm <= 20:
        raise ArgError(f"--error-mm must be in 0..20, not {a.error_mm:g}")
    command.use_cpu()
    if a.held_out:
        return held_out(a)
    run = runs.load_run(a.run)
    pi = runs.load_policy(run)
    out = {}
    for name, ctx in SCENES.items():
        with evaluate.eval_env(run["cfg"]["task"], pi, context=ctx, roi=run["cfg"]["roi"], e_r_mm=20.0) as env:
            row = evaluate.evaluate(env, pi, a.episodes, evaluate.EVAL_SEED + run["cfg"]["seed"], log=lambda *_: None)
        out[name] = row["success_rate"]
        print(f"{name:24s} SR at 20 mm {row['success_rate']:.2f}", flush=True)
    cli.check_dir_writable(a.run, "the run dir")
    with open(os.path.join(a.run, "touch.json"), "w") as f:
        json.dump({"world": evaluate.sim.WORLD, "episodes": a.episodes, "sr_20mm": out}, f, indent=1)


if __name__ == "__main__":
    sys.exit(cli.command("touch", main))
