"""objects.py: why a policy fails among workbench objects (issue 53), measured without changing the policy:
what its task ROI shows there, whether its action follows the objects, and whether the hand-designed part,
which sees no image, is disturbed by them.

    python tools/objects.py "results/robust/peg-*-imgnorm-image-s*"                 # -> results/objects/family/
    python tools/objects.py "results/robust/peg-*-imgnorm-image-s*" --scenes issue  # the issue's blocks
    python tools/objects.py --docs docs                  # docs/objects.md and its figures from results/objects

In held-out scenes at the largest error (20 mm), each run's policy meets the same episodes (evaluate's held-out
seeds, the same scenes) four ways:
- seen: as evaluation runs it; the policy sees the objects;
- blind: the physics holds the objects, but each image the policy gets is rendered with them taken away
  (the same pose, the same sensor noise): what the objects do through the image alone;
- hand: the hand-designed part alone (a zero residual), which sees no image: what the objects do to it they
  do by touch; hand-away: the same with the objects moved 5 m away (the same bodies in the solver, out of reach).
Per step of `seen`: how far the action moves when the objects leave the image (the norm of a - a_blind over
the three force actions), the share of the ROI's pixels the objects change (by more than CHANGED grey levels),
and any contact between the tool and the objects. The scenes: the `objects` family's held-out ones, or
(--scenes issue) the kind of scene issue 53's table found the peg failing in.
"""
import dataclasses
import json
import os
import re
import signal
import sys

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\nobjects: interrupted\n"), os._exit(130)))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the core modules, one folder up
import cli  # noqa: E402
import command  # noqa: E402
import contexts  # noqa: E402
import evaluate  # noqa: E402
import pages  # noqa: E402
import results  # noqa: E402
import runs  # noqa: E402
import scene  # noqa: E402
import sim  # noqa: E402
from cli import ArgError  # noqa: E402

CONTEXT, ERROR_MM = "objects:test", 20.0
# --scenes issue: blocks a scene, their side, height and centre's distance from the axis (m)
ISSUE_BLOCKS = (2, 4), (0.02, 0.03), (0.01, 0.02), (0.03, 0.06)
CHANGED = 8                  # grey levels: a pixel the objects change (the shot noise is drawn alike in both images)
CONDITIONS = ("seen", "blind", "hand", "hand-away")
SHOWN = 4                    # episodes the figure shows
SMOOTH = 2.0                 # px: the saliency shown is blurred by a Gaussian of this sigma (one pixel's is noise)


def send_away(world):
    """The world's objects moved 5 m under the table, where nothing touches them and no camera sees them."""
    for b in world.objects:
        world.bc.resetBasePositionAndOrientation(b, [0.0, 0.0, -5.0], [0.0, 0.0, 0.0, 1.0])


class Mirror:
    """A second world, the first's context without its objects, that renders what the first's camera would see
    were they gone: before each render it takes the first's board and arm poses (its physics never steps), so
    that the first world's solver keeps its history and an episode seen is evaluation's to the bit."""

    def __init__(self, world):
        self.world, self.twin, self.ctx = world, None, None

    def render_roi(self, roi, size):
        w = self.world
        if self.ctx != w.context:                   # a new scene (each episode rebuilds the first world)
            if self.twin is not None:
                self.twin.close()
            self.ctx = w.context
            self.twin = scene.World(w.task, w.base_clearance, ft_noise=w.ft_noise, image_noise=w.image_noise,
                                    context=dataclasses.replace(w.context, objects=()))
        t, bc = self.twin, w.bc
        for a, b in zip(w.plate + [b for b, _ in w.parts], t.plate + [b for b, _ in t.parts]):
            t.bc.resetBasePositionAndOrientation(b, *bc.getBasePositionAndOrientation(a))
        for j in w.arm:
            t.bc.resetJointState(t.robot, j, bc.getJointState(w.robot, j)[0])
        t.noise_rng.bit_generator.state = w.noise_rng.bit_generator.state
        img = t.render_roi(roi, size)
        w.noise_rng.bit_generator.state = t.noise_rng.bit_generator.state
        return img

    def close(self):
        if self.twin is not None:
            self.twin.close()


def twin_renders(env, blind, last):
    """Make env's world render each ROI image twice, with and without the objects (the second by a Mirror), from
    the same sensor noise; the env gets the blind one where `blind`, and last['seen'], last['blind'] hold both.
    The noise stream goes on as after one render, and the physics as without the twin. Returns the Mirror."""
    w, render, mirror = env.world, env.world.render_roi, Mirror(env.world)

    def both(roi, size=sim.IMG):
        s0 = w.noise_rng.bit_generator.state
        last["seen"] = render(roi, size)
        s1 = w.noise_rng.bit_generator.state
        w.noise_rng.bit_generator.state = s0
        last["blind"] = mirror.render_roi(roi, size)
        w.noise_rng.bit_generator.state = s1
        return last["blind"] if blind else last["seen"]
    w.render_roi = both
    return mirror


def issue_scene(rng):
    """A scene of the kind issue 53's table found the peg failing in: 2-4 blocks 2-3 cm across and 1-2 cm tall,
    their centres 3-6 cm from the hole, on the board, drawn from rng (within the tool's reach, unlike the family)."""
    n, side, tall, ring = ISSUE_BLOCKS
    out = []
    for _ in range(rng.integers(n[0], n[1] + 1)):
        while True:
            he = (*(rng.uniform(*side, 2) / 2), rng.uniform(*tall) / 2)
            a, d = rng.uniform(0, 2 * np.pi), rng.uniform(*ring)
            xy = np.array([d * np.cos(a), d * np.sin(a)])
            if np.all(np.abs(xy) + he[:2] <= contexts.BOARD_HALF) and not contexts.overlaps(xy, he, out):
                break
        out.append((tuple(round(float(v), 4) for v in he), tuple(round(float(v), 4) for v in xy),
                    contexts.PART_COLOURS[rng.integers(len(contexts.PART_COLOURS))]))
    return scene.Context(objects=tuple(out), on_board=True)


def move_away_on_rebuild(world):
    """From now on the world's objects stand 5 m under the table from each rebuild (each episode) on."""
    rebuild = world.rebuild

    def rebuild_away(ctx=None):
        rebuild(ctx)
        send_away(world)
    world.rebuild = rebuild_away


def touching(world):
    """Whether the robot touches any of the context's objects now."""
    return any(world.bc.getContactPoints(bodyA=world.robot, bodyB=b) for b in world.objects)


def episode_env(run, pi, scenes):
    """The env a run's policy is studied in: evaluation's, its scenes those of `scenes` (family or issue)."""
    env = evaluate.eval_env(run["cfg"]["task"], pi, context=CONTEXT, roi=run["cfg"]["roi"], e_r_mm=ERROR_MM)
    if scenes == "issue":                                   # a scene each episode, from the episode's seed
        env._episode_context = lambda: issue_scene(env.scene_rng)
    return env


def study_run(run, episodes, scenes="family", log=print):
    """The conditions' episodes of one run: {condition: [per episode {success, touched, ...}]}."""
    pi = runs.load_policy(run)
    seed = evaluate.EVAL_SEED + run["cfg"]["seed"]
    out = {c: [] for c in CONDITIONS}
    for cond in CONDITIONS:
        with episode_env(run, pi, scenes) as env:
            last = {}
            mirror = twin_renders(env, cond == "blind", last)
            if cond == "hand-away":
                move_away_on_rebuild(env.world)
            for k in range(episodes):
                ep = {"touched": False, "shift": [], "changed": []}

                def act(obs):
                    if cond.startswith("hand"):
                        return np.zeros(6)
                    a = pi(obs)
                    if cond == "seen":
                        a_blind = pi({**obs, "image": last["blind"][None]})
                        ep["shift"].append(float(np.linalg.norm(a[:3] - a_blind[:3])))
                        ep["changed"].append(float(np.mean(np.abs(last["seen"].astype(int) - last["blind"]) > CHANGED)))
                    return a

                def on_step(obs, r, info):
                    ep["touched"] |= touching(env.world)
                term, info, _ = sim.run_episode(env, act, seed=evaluate.episode_seed(seed, k), on_step=on_step)
                ep.update(success=bool(term), offset=info["goal_offset"].tolist(),
                          objects=len(env.world.context.objects))
                out[cond].append(ep)
            mirror.close()
            log(f"{run['dir']}: {cond} SR {np.mean([e['success'] for e in out[cond]]):.2f}")
    return out


def first_images(run, scenes, k=SHOWN):
    """The first image of episodes 0..k-1 of a run's study, the same without the objects, and the saliency."""
    pi, seed, shown = runs.load_policy(run), evaluate.EVAL_SEED + run["cfg"]["seed"], []
    with episode_env(run, pi, scenes) as env:
        last = {}
        mirror = twin_renders(env, False, last)
        for ep in range(k):
            obs, _ = env.reset(seed=evaluate.episode_seed(seed, ep))
            shown.append({"seen": last["seen"], "blind": last["blind"], "saliency": results.saliency(pi, obs)})
        mirror.close()
    return shown


def summary(out):
    """One run's numbers: SR per condition, episodes touched, the action's mean shift and the ROI's share changed."""
    seen = out["seen"]
    return {**{f"sr_{c}": float(np.mean([e["success"] for e in out[c]])) for c in CONDITIONS},
            **{f"touched_{c}": int(sum(e["touched"] for e in out[c])) for c in CONDITIONS[:3]},
            "shift": float(np.mean([s for e in seen for s in e["shift"]])),
            "shift_first": float(np.mean([e["shift"][0] for e in seen])),
            "changed_first": float(np.mean([e["changed"][0] for e in seen])),
            "hand_moved_mm": 1000 * float(max(np.abs(np.subtract(a["offset"][:3], b["offset"][:3])).max()
                                             for a, b in zip(out["hand"], out["hand-away"]))),
            "episodes": len(seen)}


SCENES = {"issue": "scenes of the kind issue 53 found the peg failing in: 2-4 blocks 2-3 cm across and 1-2 cm tall, "
                   "their centres 3-6 cm from the hole (within the tool's reach)",
          "family": "held-out scenes of the `objects` family (contexts.py)"}


def write_docs(out, docs, log=print):
    """docs/objects.md's block `objects` (pages.py): a table for each kind of scenes and task, from the JSONs under
    `out`, and a figure each."""
    studies = [runs.read_json(os.path.join(out, sc, f)) for sc in SCENES if os.path.isdir(os.path.join(out, sc))
               for f in sorted(os.listdir(os.path.join(out, sc))) if f.endswith(".json")]
    if not studies:
        raise ArgError(f"{out}: no study here (run tools/objects.py RUNS first)")
    md = [f"Made by `python tools/objects.py --docs docs` from `{out}` (world {sim.WORLD}). Each run meets the same "
          f"held-out scenes at {ERROR_MM:g} mm (evaluation's seeds) four ways: seeing the objects (seen); blind to "
          "them (the physics holds them, each image the policy gets is rendered without them, with the same sensor "
          "noise); the hand-designed part alone, which sees no image (hand); and the same with the objects moved 5 m "
          "away, the same bodies in the solver but out of reach (hand-away). The blind image is rendered by a second "
          "world that mirrors the first's board and arm without the objects, so `seen` is evaluation's episodes to the "
          "bit. "
          "Each cell: the mean over the runs (seeds) with a 95 % bootstrap interval over them, then each run's."]
    setting = lambda r: re.sub(r"-s\d+$", "", os.path.basename(os.path.normpath(r["dir"])))  # noqa: E731
    groups = sorted({(r["scenes"], r["task"], setting(r)) for r in studies},
                    key=lambda k: (list(SCENES).index(k[0]), k[1], "imgnorm" not in k[2], k[2]))
    for sc, task, name in groups:
        mine = [r for r in studies if (r["scenes"], r["task"], setting(r)) == (sc, task, name)]
        rows = [r["summary"] for r in mine]
        md += ["", f"### {task}, `{name}`", "",
               f"In {SCENES[sc]}: {len(mine)} runs, {rows[0]['episodes']} episodes each a condition: "
               + ", ".join(f"`{os.path.basename(os.path.normpath(r['dir']))}`" for r in mine) + ".", "",
               "| measure | mean over runs (95 % interval) | per run |", "|---|---|---|"]
        total = lambda key: sum(r[key] for r in rows)  # noqa: E731
        sr = lambda key: np.mean([r[key] for r in rows])  # noqa: E731
        md[-2:-2] = [f"Blind to the objects the policy inserts {sr('sr_blind'):.2f}, seeing them {sr('sr_seen'):.2f}. "
                     f"The tool touched an object in {total('touched_seen')} of {len(rows) * rows[0]['episodes']} "
                     f"episodes seeing them, {total('touched_blind')} blind and "
                     f"{total('touched_hand')} with the hand-designed part alone.", ""]
        line = lambda name, key, f="{:.2f}": md.append(  # noqa: E731
            f"| {name} | {runs.ci([r[key] for r in rows])} | {' / '.join(f.format(r[key]) for r in rows)} |")
        line("SR, the policy seeing the objects", "sr_seen")
        line("SR, the same episodes, the objects out of the policy's images (blind)", "sr_blind")
        line("SR, the hand-designed part alone (zero residual; it sees no image)", "sr_hand")
        line("SR, the hand-designed part alone, the objects 5 m away", "sr_hand-away")
        line("the hand-designed part's end pose, objects in place against 5 m away: largest difference, mm",
             "hand_moved_mm", "{:.3f}")
        line("share of the ROI's pixels the objects change, first image", "changed_first")
        line("action shift, the norm of a - a_blind (force part, at most 3.46), first step", "shift_first")
        line("action shift, every step", "shift")
        for c in CONDITIONS[:3]:
            line(f"episodes in which the tool touched an object ({c})", f"touched_{c}", "{:.0f}")
        fig = f"objects-{sc}-{name}.png"          # (fig-*: the report's own, which it redraws)
        md += ["", f"![{task}: first images with the objects, without them, and the saliency]({fig})", "",
               f"*{task}, `{os.path.basename(os.path.normpath(mine[0]['dir']))}`: the first image of its first {SHOWN} "
               "episodes (the task ROI at the start, 80 x 80), the same without the objects, and the saliency of the "
               f"lateral force actions there (|dF_x/dI| + |dF_y/dI|, blurred over {SMOOTH:g} px).*"]
        plot_shown(first_images(runs.load_run(mine[0]["dir"]), sc), os.path.join(docs, fig))
    page = os.path.join(docs, "objects.md")
    if not os.path.exists(page) or not pages.fill(page, {"objects": "\n".join(md)}, log):
        raise ArgError(f"{page}: no block `objects` (<!-- report: objects --> ... <!-- end -->) to fill")


def plot_shown(shown, path):
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(3, len(shown), figsize=(2.4 * len(shown), 7.4), squeeze=False)
    for j, s in enumerate(shown):
        for i, (key, cmap) in enumerate((("seen", "gray"), ("blind", "gray"), ("saliency", "hot"))):
            img = s[key] if cmap == "gray" else cv2.GaussianBlur(s[key], (0, 0), SMOOTH)
            axs[i][j].imshow(img, cmap=cmap, **({"vmin": 0, "vmax": 255} if cmap == "gray" else {}))
            axs[i][j].set_xticks([]), axs[i][j].set_yticks([])
        axs[0][j].set_title(f"episode {j}", fontsize=9)
    for i, name in enumerate(("with objects", "without", "saliency")):
        axs[i][0].set_ylabel(name)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    ap = cli.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="?", default="", help="comma-separated glob patterns of run directories (with "
                    "policy.pt) to study")
    ap.add_argument("--episodes", type=int, default=20, help="held-out episodes a run and condition (default: 20)")
    ap.add_argument("--scenes", choices=tuple(SCENES), default="family", help="the objects family's held-out "
                    "scenes (default), or the issue's kind: 2-4 blocks 2-3 cm, 1-2 cm tall, 3-6 cm from the hole")
    ap.add_argument("--out", default="results/objects", help="the studies' folder: <out>/<scenes>/<run>.json "
                    "(default: results/objects)")
    ap.add_argument("--docs", default="", help="fill objects.md's block and write its figures in this folder, from --out")
    a = ap.parse_args(argv)
    if a.episodes < 1:
        raise ArgError(f"--episodes must be at least 1, not {a.episodes}")
    if not a.runs and not a.docs:
        raise ArgError("name runs to study, or --docs DIR to write the page from the studies in --out")
    command.use_cpu()
    chosen = [runs.load_run(d) for d in runs.match_runs(a.runs) if os.path.exists(os.path.join(d, "policy.pt"))] \
        if a.runs else []
    if a.runs and not chosen:
        raise ArgError(f"{a.runs!r}: no run with a policy.pt")
    other = [r["dir"] for r in chosen if (r["eval"] or {}).get("world") != sim.WORLD]
    if other:
        raise ArgError(f"{other[0]}: not trained in world {sim.WORLD} (its eval.json says otherwise)")
    folder = os.path.join(a.out, a.scenes)
    for d in ([folder] if chosen else []) + ([a.docs] if a.docs else []):
        cli.check_dir_writable(d, "the output folder")
        os.makedirs(d, exist_ok=True)
    for run in chosen:
        out = study_run(run, a.episodes, a.scenes)
        res = {"dir": run["dir"], "task": run["cfg"]["task"], "world": sim.WORLD, "scenes": a.scenes,
               "error_mm": ERROR_MM, "summary": summary(out), "episodes": out}
        with open(os.path.join(folder, os.path.basename(os.path.normpath(run["dir"])) + ".json"), "w") as f:
            json.dump(res, f, indent=1)
        print(f"{run['dir']}: {json.dumps(res['summary'])}", flush=True)
    if a.docs:
        write_docs(a.out, a.docs)


if __name__ == "__main__":
    sys.exit(cli.command("objects", main))
