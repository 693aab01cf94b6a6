"""objects.py: why a policy fails among workbench objects (issue 53), measured without changing the policy:
what its task ROI shows there, whether its action follows the objects, and whether the hand-designed part,
which sees no image, is disturbed by them.

    python tools/objects.py "results/robust/peg-*-imgnorm-image-s*" --out results/objects --docs docs

In held-out scenes of the `objects` family (scene.FAMILIES) at the largest error (20 mm), each run's policy
meets the same episodes (evaluate's held-out seeds, the same scenes) three ways:
- seen: as evaluation runs it; the policy sees the objects;
- blind: the physics holds the objects, but each image the policy gets is rendered with them taken away
  (the same pose, the same sensor noise): what the objects do through the image alone;
- hand: the hand-designed part alone (a zero residual), which sees no image: what the objects do to it they
  do by touch; hand-train: the same in the training scene (the same errors), where its end pose should be the same.
Per step of `seen`: how far the action moves when the objects leave the image (|a - a_blind| over the three
force actions), the share of the ROI's pixels the objects change (by more than CHANGED grey levels), and any
contact between the tool and the objects. Writes <out>/<run name>.json a run (its episodes, per condition),
and with --docs <docs>/OBJECTS.md (the table, over seeds: mean with a 95 % bootstrap interval) and
<docs>/fig-objects-<task>.png (the first image of a few episodes, the same without the objects, and the policy's
saliency there).
"""
import contextlib
import json
import os
import signal
import sys

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\nobjects: interrupted\n"), os._exit(130)))

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the core modules, one folder up
import evaluate  # noqa: E402
import figures  # noqa: E402
import report  # noqa: E402
import sim  # noqa: E402
import tacrl  # noqa: E402
from tacrl import ArgError  # noqa: E402

CONTEXT, ERROR_MM = "objects:test", 20.0
CHANGED = 8                  # grey levels: a pixel the objects change (the shot noise is drawn alike in both images)
CONDITIONS = ("seen", "blind", "hand", "hand-train")
SHOWN = 4                    # episodes the figure shows


@contextlib.contextmanager
def objects_away(world):
    """The world's objects moved 5 m under the table for a moment (nothing touches them there), then back."""
    bc = world.bc
    poses = [bc.getBasePositionAndOrientation(b) for b in world.objects]
    for b in world.objects:
        bc.resetBasePositionAndOrientation(b, [0.0, 0.0, -5.0], [0.0, 0.0, 0.0, 1.0])
    try:
        yield
    finally:
        for b, (pos, q) in zip(world.objects, poses):
            bc.resetBasePositionAndOrientation(b, pos, q)


def twin_renders(env, blind, last):
    """Make env's world render each ROI image twice, with and without the objects, from the same sensor noise;
    the env gets the blind one where `blind`, and last['seen'], last['blind'] hold both. The noise stream
    goes on as after one render, so that `seen` episodes are evaluation's to the bit."""
    w, render = env.world, env.world.render_roi

    def both(roi, size=sim.IMG):
        s0 = w.noise_rng.bit_generator.state
        last["seen"] = render(roi, size)
        s1 = w.noise_rng.bit_generator.state
        w.noise_rng.bit_generator.state = s0
        with objects_away(w):
            last["blind"] = render(roi, size)
        w.noise_rng.bit_generator.state = s1
        return last["blind"] if blind else last["seen"]
    w.render_roi = both


def touching(world):
    """Whether the robot touches any of the context's objects now."""
    return any(world.bc.getContactPoints(bodyA=world.robot, bodyB=b) for b in world.objects)


def study_run(run, episodes, log=print):
    """The three conditions' episodes of one run: {condition: [per episode {success, touched, ...}]} and the
    first steps' images of `seen` for the figure."""
    pi = report.load_policy(run)
    seed = evaluate.EVAL_SEED + run["cfg"]["seed"]
    out, shown = {c: [] for c in CONDITIONS}, []
    for cond in CONDITIONS:
        ctx = "train" if cond == "hand-train" else CONTEXT
        with evaluate.eval_env(run["cfg"]["task"], pi, context=ctx, roi=run["cfg"]["roi"], e_r_mm=ERROR_MM) as env:
            last = {}
            twin_renders(env, cond == "blind", last)
            for k in range(episodes):
                ep = {"touched": False, "shift": [], "changed": []}

                def act(obs):
                    if cond.startswith("hand"):
                        return np.zeros(6)
                    a = pi(obs)
                    if cond == "seen":
                        a_blind = pi({**obs, "image": last["blind"]})
                        ep["shift"].append(float(np.linalg.norm(a[:3] - a_blind[:3])))
                        ep["changed"].append(float(np.mean(np.abs(last["seen"].astype(int) - last["blind"]) > CHANGED)))
                        if len(ep["shift"]) == 1 and len(shown) < SHOWN:
                            shown.append({"seen": last["seen"].copy(), "blind": last["blind"].copy(),
                                          "saliency": report.saliency(pi, obs), "episode": k})
                    return a

                def on_step(obs, r, info):
                    ep["touched"] |= touching(env.world)
                term, info, _ = sim.run_episode(env, act, seed=evaluate.episode_seed(seed, k), on_step=on_step)
                ep.update(success=bool(term), offset=info["goal_offset"].tolist(), steps=len(ep["shift"]) if cond == "seen" else None,
                          objects=len(env.world.context.objects))
                out[cond].append(ep)
            log(f"{run['dir']}: {cond} SR {np.mean([e['success'] for e in out[cond]]):.2f}")
    return out, shown


def summary(out):
    """One run's numbers: SR per condition, episodes touched, the action's mean shift and the ROI's share changed."""
    seen = out["seen"]
    return {**{f"sr_{c}": float(np.mean([e["success"] for e in out[c]])) for c in CONDITIONS},
            **{f"touched_{c}": int(sum(e["touched"] for e in out[c])) for c in CONDITIONS[:3]},
            "shift": float(np.mean([s for e in seen for s in e["shift"]])),
            "shift_first": float(np.mean([e["shift"][0] for e in seen])),
            "changed_first": float(np.mean([e["changed"][0] for e in seen])),
            "hand_moved_mm": 1000 * float(max(np.abs(np.subtract(a["offset"][:3], b["offset"][:3])).max()
                                             for a, b in zip(out["hand"], out["hand-train"]))),
            "episodes": len(seen)}


def ci(values):
    mean, lo, hi = figures.bootstrap_band([[v] for v in values])
    return f"{mean[0]:.2f} ({lo[0]:.2f}-{hi[0]:.2f})"


def write_docs(results, shown, docs, log=print):
    """docs/OBJECTS.md's tables, a task each, from the runs' summaries, and fig-objects-<task>.png."""
    md = ["# Why the peg fails among workbench objects (issue 53)", "",
          f"Made by `python tools/objects.py` (world {sim.WORLD}). Each run meets the same held-out scenes of the "
          f"`objects` family at {ERROR_MM:g} mm (evaluation's seeds) three ways: seeing the objects, blind to them "
          "(the physics holds them, the policy's images are rendered without them), and the hand-designed part alone. "
          "Each cell: the mean over the runs (seeds) with a 95 % bootstrap interval over them, then each run's."]
    for task in sorted({r["task"] for r in results}):
        mine = [r for r in results if r["task"] == task]
        rows, n = [r["summary"] for r in mine], mine[0]["summary"]["episodes"]
        md += ["", f"## {task}: {len(mine)} runs, {n} episodes each and condition", "",
               "Runs: " + ", ".join(f"`{os.path.basename(os.path.normpath(r['dir']))}`" for r in mine) + ".", "",
               "| measure | mean over runs (95 % interval) | per run |", "|---|---|---|"]
        line = lambda name, key, f="{:.2f}": md.append(  # noqa: E731
            f"| {name} | {ci([r[key] for r in rows])} | {' / '.join(f.format(r[key]) for r in rows)} |")
        line("SR, the policy seeing the objects", "sr_seen")
        line("SR, the same episodes, the objects out of the policy's images (blind)", "sr_blind")
        line("SR, the hand-designed part alone (zero residual; it sees no image)", "sr_hand")
        line("SR, the hand-designed part alone in the training scene, the same errors", "sr_hand-train")
        line("the hand-designed part's end pose, objects against training scene: largest difference, mm",
             "hand_moved_mm", "{:.3f}")
        line("share of the ROI's pixels the objects change, first image", "changed_first")
        line("action shift, the norm of a - a_blind (force part, at most 3.46), first step", "shift_first")
        line("action shift, every step", "shift")
        for c in CONDITIONS[:3]:
            line(f"episodes in which the tool touched an object ({c})", f"touched_{c}", "{:.0f}")
        fig = f"fig-objects-{task}.png"
        md += ["", f"![{task}: the first image of a few episodes with the objects, without them, and the saliency]({fig})",
               "", f"*{task}, the first run: its first image in {len(shown[task])} episodes (the task ROI at the "
               "start, 80 x 80), the same without the objects, and the saliency of the lateral force actions there "
               "(|dF_x/dI| + |dF_y/dI|).*"]
        plot_shown(shown[task], os.path.join(docs, fig))
    with open(os.path.join(docs, "OBJECTS.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    log(f"wrote {docs}/OBJECTS.md and its figures")


def plot_shown(shown, path):
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(3, len(shown), figsize=(2.4 * len(shown), 7.4), squeeze=False)
    for j, s in enumerate(shown):
        for i, (key, cmap) in enumerate((("seen", "gray"), ("blind", "gray"), ("saliency", "hot"))):
            axs[i][j].imshow(s[key], cmap=cmap, **({"vmin": 0, "vmax": 255} if cmap == "gray" else {}))
            axs[i][j].set_xticks([]), axs[i][j].set_yticks([])
        axs[0][j].set_title(f"episode {s['episode']}", fontsize=9)
    for i, name in enumerate(("with objects", "without", "saliency")):
        axs[i][0].set_ylabel(name)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    ap = tacrl.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", help="comma-separated glob patterns of run directories (with policy.pt)")
    ap.add_argument("--episodes", type=int, default=20, help="held-out episodes a run and condition (default: 20)")
    ap.add_argument("--out", default="results/objects", help="folder for a JSON a run (default: results/objects)")
    ap.add_argument("--docs", default="", help="also write OBJECTS.md and fig-objects.png into this folder")
    a = ap.parse_args(argv)
    if a.episodes < 1:
        raise ArgError(f"--episodes must be at least 1, not {a.episodes}")
    runs = [report.load_run(d) for d in report.match_runs(a.runs) if os.path.exists(os.path.join(d, "policy.pt"))]
    if not runs:
        raise ArgError(f"{a.runs!r}: no run with a policy.pt")
    other = [r["dir"] for r in runs if (r["eval"] or {}).get("world") != sim.WORLD]
    if other:
        raise ArgError(f"{other[0]}: not trained in world {sim.WORLD} (its eval.json says otherwise)")
    for d in [a.out] + ([a.docs] if a.docs else []):
        os.makedirs(d, exist_ok=True)
        tacrl.check_dir_writable(d, "the output folder")
    tacrl.use_cpu(tacrl.Config(device="cpu"))
    results, shown = [], {}
    for run in runs:
        out, first = study_run(run, a.episodes)
        shown.setdefault(run["cfg"]["task"], first)
        res = {"dir": run["dir"], "task": run["cfg"]["task"], "world": sim.WORLD, "context": CONTEXT, "error_mm": ERROR_MM, "summary": summary(out),
               "episodes": out}
        with open(os.path.join(a.out, os.path.basename(os.path.normpath(run["dir"])) + ".json"), "w") as f:
            json.dump(res, f, indent=1)
        print(f"{run['dir']}: {json.dumps(res['summary'])}", flush=True)
        results.append(res)
    if a.docs:
        write_docs(results, shown, a.docs)


if __name__ == "__main__":
    sys.exit(tacrl.command("objects", main))
