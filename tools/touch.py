"""touch.py: which part of the touch family a policy loses in (issue 53): the same held-out episodes at 20 mm in
scenes that each change one thing the part touches to an end of the family's range, the rest as in training.

    python tools/touch.py results/contexts/peg-task-s0 --episodes 20      # -> one line a scene, and touch.json
"""
import json
import os
import signal
import sys

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\ntouch: interrupted\n"), os._exit(130)))

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the core modules, one folder up
import cli  # noqa: E402
import command  # noqa: E402
import contexts  # noqa: E402
import evaluate  # noqa: E402
import report  # noqa: E402
import scene  # noqa: E402
from cli import ArgError  # noqa: E402

T = np.radians(1.0)
SCENES = {"training": scene.Context(),
          "oiled (0.10)": scene.Context(friction=contexts.TOUCH_FRICTION[0]),
          "dry (0.70)": scene.Context(friction=contexts.TOUCH_FRICTION[1]),
          "0.05 mm clearance": scene.Context(clearance=contexts.TOUCH_CLEARANCE[0]),
          "0.3 mm clearance": scene.Context(clearance=contexts.TOUCH_CLEARANCE[1]),
          "tilted 1 deg about x": scene.Context(tilt=(T, 0.0)),
          "tilted 1 deg about y": scene.Context(tilt=(0.0, T))}


def main(argv=None):
    ap = cli.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", help="a run directory with policy.pt")
    ap.add_argument("--episodes", type=int, default=20, help="held-out episodes a scene (default: 20)")
    a = ap.parse_args(argv)
    if a.episodes < 1:
        raise ArgError(f"--episodes must be at least 1, not {a.episodes}")
    run = report.load_run(a.run)
    pi = report.load_policy(run)
    command.use_cpu()
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
