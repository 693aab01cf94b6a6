"""report.py: the paper's experiments, re-made from run directories (Sec. 5.1.2-5.1.5): Table 1
(ours against the two-step, vanilla and visual baselines), Table 2 (the training context and unseen
ones), the observation, curriculum and ROI ablations (Figs. 9-11), context generalization (Fig. 12)
and one episode's behaviour (Fig. 16), written to docs/RESULTS.md with its figures. A run directory
lives on the machine that trained it (its checkpoint and replay are hundreds of MB); --archive
copies what the report reads (under 1 MB a run) to results/, which the repository keeps, so the
report can be regenerated from a fresh clone:

    python tools/report.py --archive "runs/table1/*" --to results/table1    # finished runs -> results/table1/<run>/
    python tools/report.py                           # results/{table1,contexts,gear-*} -> docs/RESULTS.md, fig-*.png

It evaluates what it needs and has not got yet (the two-step baseline, the unseen contexts) and
caches those rows beside the runs. docs/results-notes.md, the hand-written reading of the numbers, goes
under the tables its sections are titled after (read_notes).
"""
import csv
import glob
import json
import os
import re
import shutil
import signal
import sys
import tempfile
from dataclasses import asdict, fields

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\nreport: interrupted\n"), os._exit(130)))

import numpy as np  # noqa: E402
import torch  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the core modules, one folder up
import cli  # noqa: E402
import baselines  # noqa: E402
import command  # noqa: E402
import contexts  # noqa: E402
import evaluate  # noqa: E402
import figures  # noqa: E402
import rundir  # noqa: E402
import sweep  # noqa: E402
import sim  # noqa: E402
import tacrl  # noqa: E402
from cli import ArgError  # noqa: E402


# The paper's numbers, next to which ours stand. Table 1: simulated peg, 20 trials after 200 episodes.
PAPER_CRITICS = " (critic multimodal)"        # a learned row with the paper's critics (ours are privileged: README)
LEARNED = ("vanilla", "visual", "keypoint", "ours")
PAPER_TABLE1 = {"two-step": "0.533, 19.00 +- 5.75, 13.21 / 13.22 / 9.78",
                "vanilla": "did not learn", "visual": "did not learn", "keypoint": "0.96, 4.27 +- 2.97, -",
                "ours": "1.00, 2.41 +- 1.93, 12.14 / 6.92 / 3.23"}
# Table 2 (real robot), success rate at 5/10/15/20 mm: the rows that the paper's layout pins down
PAPER_TABLE2 = {("peg", "train"): "1.00 / 1.00 / 1.00 / 0.80", ("peg", "loc-1"): "1.00 / 1.00 / 0.90 / 0.75",
                ("gear", "train"): "1.00 / 1.00 / 0.95 / 0.70"}
TABLE1_ROWS = {"vanilla": "vanilla RL (`--vanilla`: no base policy)", "visual": "visual RL (`--obs v`)",
               "keypoint": "keypoint RL (`--obs ts-ptk`)", "ours": "ours (TA-MRP + adaptive curriculum)",
               "two-step": "two-step (visual servo, spiral search)"}
# our stand-ins for Table 2's 'unseen 1' and 'unseen 2': the real board at two other places
UNSEEN = ("loc-1", "loc-2")
TABLE2_LABELS = {"train": "training context", "loc-1": "unseen 1 (`loc-1`)", "loc-2": "unseen 2 (`loc-2`)"}
# Fig. 12 as the paper made it (Sec. 5.1.4): the gear ROI ablation's ROI 300 against its full view (the paper's
# ROI-800), at four other table locations (scored by their mean) and with objects added to the background
FIG12_LOCATIONS, FIG12_BACKGROUND = ("loc-1", "loc-2", "loc-3", "loc-4"), "bg-objects"
VIEWS = {"task": "task attention", "full": "full view"}       # the quickstart's view and its full-view twin
FIG12_VIEWS = {"gear": {"300": "ROI 300", "full": "full view (ROI 800)"},       # the paper's: its ROI ablation
               "peg": VIEWS}                                                   # ours: the paper has no peg ablation
ABLATIONS = {"gear-obs": "Fig. 9, observations (P-T, time-series P-T, time-series P-T-V; 200 episodes)",
             "gear-curriculum": "Fig. 10, curricula (adaptive, g2-c30, g2-c10, g2-c2, none; 300 episodes)",
             "gear-roi": "Fig. 11, ROI windows (task attention, full, 300, 200, 100x160; 200 episodes)"}
# Fig. 12 is the simulation's (Sec. 5.1.4, the gear ablations), scored by the average cumulative reward
PAPER_FIG12 = ("The paper (simulation, the gear's ROI ablation, Fig. 12, average cumulative reward): ROI-300 61.19 -> "
               "54.73 (new background), 69.23 -> 46.46 (new locations); ROI-800, the full view, 61.12 -> -23.06 and "
               "59.51 -> -14.65.")
LEVELS = (5.0, 10.0, 15.0, 20.0)
PAPER_ABLATIONS = {   # what the paper says of each ablation's curves (Sec. 5.1.4); it gives no numbers beside these
    "obs": "The paper (Fig. 9, gear, the final error range after 200 episodes): all three learn at 2 mm; P-T tolerates "
           "only 5 mm, time-series P-T more but limited, time-series P-T-V is robust under 10 mm.",
    "curriculum": "The paper (Fig. 10, gear, 300 episodes): without curriculum, 10 mm reaches SR 0.9 and reward 70, "
                  "20 mm SR 0.6 and reward 20, 30 mm less; at 30 mm every curriculum beats no curriculum, g2-c10 "
                  "learns faster than g2-c30, and g2-c2 behaves like g2-c10.",
    "roi": "The paper (Fig. 11, gear, 200 episodes): ROI-100*160 reaches only 7 mm, as without vision; ROI-200*200 is "
           "robust in a limited range; ROI-300*300 and ROI-800*800 are robust in a larger range, the full view the "
           "fastest to converge.",
}
OBS_NAMES = {"pt": "P-T", "ts-pt": "Time-series P-T", "ts-ptv": "Time-series P-T-V"}
FAMILIES = {   # family: (title, curves, the paper's figure, the episodes each of its runs trains: the paper's budget)
    "methods": ("ours against the learned baselines", ("return", "sr15", "e_r_mm"), "Table 1", 200),
    "obs": ("observation ablation: Ex_r held at 10 mm, E_r adaptive", ("return", "sr15", "e_r_mm"), "Fig. 9", 200),
    "curriculum": ("curriculum ablation", ("return", "sr15", "e_r_mm", "ex_r_mm"), "Fig. 10", 300),
    "roi": ("ROI ablation", ("return", "sr15", "e_r_mm"), "Fig. 11", 200),
}
RESULTS_DIR = "results"       # the archived runs the report is built from; the repository keeps them
# what each report reads by default: an experiment's runs lie in results/<experiment of tools/sweep.py>/
REPORT_RUNS = ",".join(f"{RESULTS_DIR}/{e}/*" for e in ("table1", "contexts", *ABLATIONS))
CONTEXT_RUNS = f"{RESULTS_DIR}/contexts/*,{RESULTS_DIR}/robust/*,{RESULTS_DIR}/option/*,{RESULTS_DIR}/option-loo/*"
ARCHIVED = ("config.json", "metrics.csv", "policy.pt", "curves.png", "train.log", "critics.json")    # and eval*.json


def read_json(path):
    with open(path) as f:
        return json.load(f)


def read_world_cache(path):
    """(world, value) of a cached evaluation written by write_world_cache; one written before the world key (the
    bare value) is of the unversioned world, None; (None, None) where there is none."""
    if not os.path.exists(path):
        return None, None
    d = read_json(path)
    return (d["world"], d["value"]) if isinstance(d, dict) and set(d) == {"world", "value"} else (None, d)


def write_world_cache(path, world, value):
    with open(path, "w") as f:
        json.dump({"world": world, "value": value}, f, indent=2)


def read_config(d):
    """A run's config as a dict of today's flags, in config.json's order, and of flags retired to a git tag (the
    critics study's, and older ones) where the run's differ from what today's code computes: the report reads
    those runs too. A retired flag the report does not know is read as today's code where it is off (0, false)."""
    raw = rundir.read_config(d)
    order = list(raw)
    study = command.study_options(raw)
    known = {f.name for f in fields(tacrl.Config)}
    unknown = {k: raw.pop(k) for k in list(raw) if k not in known}
    study.update({k: v for k, v in unknown.items() if v})
    cfg = {**asdict(cli.from_dict(tacrl.Config, raw)), **study}
    return dict(sorted(cfg.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else len(order)))


def load_run(d):
    """A run dir as {'dir', 'cfg' (config dict), 'm' ({metrics column: array}), 'eval' (eval.json or None)}."""
    try:
        cfg = read_config(d)
        ev = read_json(os.path.join(d, "eval.json")) if os.path.exists(os.path.join(d, "eval.json")) else None
        metrics = rundir.read_metrics(d)
        m = {k: np.array(metrics[k]) for k in ("episode", "return", "success", "sr15", "e_r_mm", "ex_r_mm",
                                               "elapsed_s")}
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ArgError(f"{d}: a damaged run directory ({cli.describe(e)})")
    return {"dir": d, "cfg": cfg, "m": m, "eval": ev}


def load_policy(run):
    """A run's policy.pt (ArgError where it is not one, or is another task's)."""
    path = os.path.join(run["dir"], "policy.pt")
    try:
        pi = evaluate.load_policy(path)
    except ValueError as e:
        raise ArgError(f"{path}: {e}")
    if pi.meta["task"] != run["cfg"]["task"]:
        raise ArgError(f"{path}: a {pi.meta['task']} policy in a {run['cfg']['task']} run")
    return pi


def method_of(cfg):
    """'ours', 'vanilla', 'visual', 'keypoint' or the ablation variant a run trained, plus any learning setting
    that differs from the defaults (so that runs are grouped only with their like)."""
    if cfg.get("vanilla"):
        name = "vanilla"
    elif cfg["obs"] == "v":
        name = "visual"
    elif cfg["obs"] == "ts-ptk" and (cfg["curriculum"], cfg["roi"], cfg["error_mm"]) == ("adaptive", "task", 20.0):
        name = "keypoint"
    elif (cfg["obs"], cfg["curriculum"], cfg["roi"], cfg["error_mm"]) == ("ts-ptv", "adaptive", "task", 20.0):
        name = "ours"
    else:
        name = f"{cfg['obs']}, {cfg['curriculum']} to {cfg['error_mm']:g} mm, roi {cfg['roi']}"
    default = tacrl.Config()
    named = ("task", "seed", "context", "vanilla", "obs", "curriculum", "roi", "error_mm") + command.NOT_LEARNING
    changed = [f"{k} {v}" for k, v in cfg.items()         # (a retired flag is in cfg only where not today's code)
               if k not in named and (not hasattr(default, k) or v != getattr(default, k))]
    return name + (f" ({', '.join(changed)})" if changed else "")


def command_of(cfg):
    """The training command that reproduces a run: the flags whose values differ from the defaults (with the
    critics study's flags, the command of its git tag)."""
    default, flags = tacrl.Config(), ["python tacrl.py"]
    for k, v in cfg.items():
        if k in ("run_dir", "threads", "device", "resume", "track"):
            continue
        if not hasattr(default, k) or v != getattr(default, k) or k == "task":        # (a retired flag: its tag's)
            value = "" if v is True else f" {v:g}" if isinstance(v, float) else f" {v}"
            flags.append(f"--{k.replace('_', '-')}" + value)
    return " ".join(flags)


ABLATION_STATS = ("Over each setting's seeds: the first episode at the final range seed by seed; E_r, the CT and "
                  "the SR at each level their means; training success (its last 15 episodes, the paper's Fig. 10 (b) "
                  "measure) and the held-out SR at the final range (ours: 20 greedy trials a seed) the mean with its "
                  "95 % bootstrap interval (Sec. 5.1.5), each seed's in brackets.")


def ablation_table(runs, task, fam, log=print):
    """One of the paper's ablations (FAMILIES' fam) in numbers, a row a setting, each cell over its seeds (seed by
    seed in brackets): the first episode whose E_r reached the run's final range, the largest E_r and the last,
    training success over the last 15 episodes (the paper's Fig. 10 (b)), and the held-out evaluation at the final
    range (20 trials a seed) and at 5-20 mm. [] where fewer than two settings have finished runs."""
    rows = groups_of([r for r in runs if r["eval"]], task, fam)
    if len(rows) < 2:
        return []
    md = ["| setting | seeds | first episode at the final E_r | E_r most / last (mm) | training success, last 15 | "
          "eval SR at the final range | CT there (s) | eval SR at " + " / ".join(f"{x:g}" for x in LEVELS) + " mm |",
          "|---" * 8 + "|"]
    for label, seeds in sorted(rows.items()):
        first, most, last, trained, final, ct, at = [], [], [], [], [], [], []
        for r in seeds:
            m, mm = r["m"], r["cfg"]["error_mm"]
            reached = np.flatnonzero(np.asarray(m["e_r_mm"]) >= mm - 1e-6)
            first.append(str(int(m["episode"][reached[0]])) if len(reached) else "never")
            most.append(float(np.max(m["e_r_mm"])))
            last.append(float(m["e_r_mm"][-1]))
            trained.append(float(np.mean(m["success"][-15:])))      # the paper's Fig. 10 (b): the last 15
            row = next((x for x in r["eval"]["rows"] if x["error_mm"] == mm), None) \
                or eval_cached(r, "train", levels=(mm,), log=log)[0]
            final.append(row["success_rate"])
            if row["completion_time_s"]:
                ct.append(row["completion_time_s"][0])
            by_level = {x["error_mm"]: x["success_rate"] for x in r["eval"]["rows"]}
            at.append([by_level.get(x, np.nan) for x in LEVELS])
        mean = lambda v, f="{:.2f}": ci(v, f) + (f" ({' / '.join(f.format(x) for x in v)})" if len(v) > 1 else "")
        md.append(f"| {label} | {len(seeds)} | {' / '.join(first)} | {np.mean(most):.1f} / {np.mean(last):.1f} | "
                  f"{mean(trained)} | {mean(final)} | {f'{np.mean(ct):.2f}' if ct else '-'} | "
                  + " / ".join(f"{v:.2f}" for v in np.nanmean(at, axis=0)) + " |")
    return md


def groups_of(runs, task, fam):
    """The rows of one of the paper's comparisons (FAMILIES' fam) for a task: {row label: [its runs, a seed each]}."""
    groups = {}
    for r in runs:
        label = fam_of(r).get(fam)
        if r["cfg"]["task"] == task and label:
            groups.setdefault(label, []).append(r)
    return groups


def is_planned(run, plan):
    """Whether a run is the sweep's planned run `plan` (a Config), finished: its name says what it learns, its
    config how long it trained (two experiments may plan one name at two budgets: the ROI ablation's task
    attention at 200 episodes and the curriculum ablation's adaptive at 300)."""
    return os.path.basename(run["dir"]) == sweep.run_name(plan) and plan.stop_held == 0 \
        and trained_budget(run, plan.train_episodes)


def trained_budget(run, episodes):
    """Whether a run trained all of a fixed budget of episodes (--stop-held 0), as the paper's rows do."""
    cfg = run["cfg"]
    return cfg["stop_held"] == 0 and cfg["train_episodes"] == episodes == len(run["m"]["episode"])


def fam_of(run):
    """The paper's comparisons a run is a row of: families() where it trained the comparison's budget (FAMILIES,
    --stop-held 0), as the paper's rows do. A run stopped when learned, as the quickstart's, or trained for another
    number of episodes, is a row of none (Table 2, Fig. 12 and CONTEXTS.md take those)."""
    return {f: label for f, label in families(run["cfg"]).items() if trained_budget(run, FAMILIES[f][3])}


def families(cfg):
    """The paper's comparisons a run takes part in: {figure family: curve label}. Only runs with
    the default learning settings (method_of without a suffix) are compared."""
    name = method_of(cfg)
    if name.endswith(PAPER_CRITICS) and name[:-len(PAPER_CRITICS)] in LEARNED:   # a row with the paper's critics
        return {"methods": name}
    if "(" in name:
        return {}
    ours = {"obs": "ts-ptv", "curriculum": "adaptive", "roi": "task", "error_mm": 20.0, "vanilla": False}
    ours_but = lambda **kw: all(cfg[k] == v for k, v in {**ours, **kw}.items())   # noqa: E731
    fam = {}
    if name in ("ours", "vanilla", "visual", "keypoint"):
        fam["methods"] = name
    if cfg["curriculum"] == "ex10" and cfg["roi"] == "task" and not cfg.get("vanilla"):
        fam["obs"] = OBS_NAMES.get(cfg["obs"], cfg["obs"])
    if ours_but(curriculum=cfg["curriculum"], error_mm=cfg["error_mm"]) and cfg["curriculum"] != "ex10" and (
            cfg["curriculum"] in ("none", "adaptive") or cfg["error_mm"] == 30.0):   # ours: adaptive at 20 mm
        fam["curriculum"] = ("no curriculum" if cfg["curriculum"] == "none" else f"curriculum {cfg['curriculum']}") \
            + f", {cfg['error_mm']:g} mm"
    if ours_but(roi=cfg["roi"]):
        fam["roi"] = "task attention (Eq. 11)" if cfg["roi"] == "task" else f"ROI {cfg['roi']}"
    return fam


def eval_cached(run, context, levels=LEVELS, episodes=20, log=print):
    """A run's rows in `context` at `levels` (mm), of its own world: the training context's from eval.json where it
    holds them, else context_rows' cache in the run dir (the one report.py --contexts fills), else evaluated now,
    which only a run of this code's world can be (ArgError for an older one: its rows would be another world's)."""
    ev = run["eval"]
    if context == "train" and ev and ev.get("world") == sim.WORLD and ev["rows"][0]["episodes"] == episodes \
            and [r["error_mm"] for r in ev["rows"]] == list(levels):
        return ev["rows"]
    if ev and ev.get("world") != sim.WORLD:
        raise ArgError(f"{run['dir']} was made in world {ev.get('world') or 'unversioned'}: this code (world "
                       f"{sim.WORLD}) would evaluate it in another world")
    return context_rows((run["dir"], context, tuple(levels), episodes), log)


def fig12(runs, task, out_dir, log=print):
    """Fig. 12 for a task: each view's mean cumulative reward per episode (over LEVELS, 20 trials each) in the
    training context, at each of the four locations and their mean, and in the new background; the mean over
    seeds with its 95 % bootstrap interval. The gear's views are its ROI ablation's (200 episodes each), the
    peg's the quickstart's task attention and its full-view twin. Returns (markdown lines, figures)."""
    views, contexts_ = FIG12_VIEWS[task], ("train",) + FIG12_LOCATIONS + (FIG12_BACKGROUND,)
    cr = {}
    for roi, label in views.items():
        seeds = [r for r in runs if r["cfg"]["task"] == task and r["eval"] and r["cfg"]["roi"] == roi
                 and (fam_of(r).get("roi") if task == "gear" else not fam_of(r) and families(r["cfg"]).get("roi"))]
        if seeds:         # each seed's mean cumulative reward over the levels and trials
            c = {ctx: [np.mean([x["cumulative_reward"][0] for x in eval_cached(r, ctx, log=log)]) for r in seeds]
                 for ctx in contexts_}
            c["locations"] = list(np.mean([c[x] for x in FIG12_LOCATIONS], 0))      # each seed's mean over four
            cr[f"{label} ({len(seeds)} seeds)"] = c
    if len(cr) < 2:
        return [], []
    columns = {"train": "training context", "locations": "new locations (mean of 4)",
               FIG12_BACKGROUND: "new background"}
    bars = {view: {columns[k]: mean_ci(c[k]) for k in columns} for view, c in cr.items()}
    figs = [(f"fig-{task}-contexts.png", f"{task}: mean cumulative reward per episode over 5/10/15/20 mm (20 trials "
                                         "each) in the training context, at four new locations (their mean) and "
                                         "with a new background (the paper's Fig. 12; bars: 95 % bootstrap interval "
                                         "over seeds)"),
            (f"fig-{task}-views.png", f"{task}: what each view sees at the start of an episode in each context")]
    figures.plot_context_bars(bars, os.path.join(out_dir, figs[0][0]), f"{task}: the training context and unseen ones")
    figures.plot_views(task, tuple(views), contexts_, os.path.join(out_dir, figs[1][0]))
    whose = ("the ROI ablation's policies (Fig. 11's runs, 200 episodes each), as the paper's Fig. 12" if task == "gear"
             else "ours, not the paper's experiment (its Fig. 12 is the gear's ROI ablation): task attention trained "
                  "as the quickstart trains (stopped when learned), the full view as long as its twin of the same seed")
    head = ["training context"] + [f"`{x}`" for x in FIG12_LOCATIONS] + ["locations' mean", "new background"]
    keys = ["train", *FIG12_LOCATIONS, "locations", FIG12_BACKGROUND]
    md = ["", f"## Context generalization, {task} (the paper's Fig. 12)", "",
          f"From {whose}. Each cell: the mean cumulative reward per episode over 5/10/15/20 mm (20 trials each on "
          "held-out seeds), mean over seeds [95 % bootstrap interval over seeds]. The locations are `"
          + "`, `".join(FIG12_LOCATIONS) + f"` (the paper: four table locations); the new background is "
          f"`{FIG12_BACKGROUND}` (objects beside the board).", "",
          "| view | " + " | ".join(head) + " |", "|---" * (1 + len(head)) + "|"]
    md += [f"| {view} | " + " | ".join(ci(c[k], "{:.1f}") for k in keys) + " |" for view, c in cr.items()]
    return md + ["", PAPER_FIG12], figs


def mean_ci(values):
    """[mean, lo, hi]: the mean of values (one a seed) and its 95 % bootstrap interval (figures.bootstrap_band)."""
    mean, lo, hi = figures.bootstrap_band([[v] for v in values])
    return [float(mean[0]), float(lo[0]), float(hi[0])]


def ci(values, f="{:.2f}"):
    """The mean of values (one a seed) with its 95 % bootstrap interval, as the paper gives its statistics (Sec.
    5.1.5): 'mean [lo, hi]'; a single value alone; '-' for none."""
    if len(values) == 0:
        return "-"
    if len(values) == 1:
        return f.format(values[0])
    return "{} [{}, {}]".format(*(f.format(x) for x in mean_ci(values)))


def cell(row, k, f="{:.2f}"):
    v = row.get(k)
    return "-" if v is None else f"{f.format(v[0])} +- {f.format(v[1])}"


def saliency(act, obs):
    """Where in the image the lateral action looks (Fig. 16's "important regions of the image"): the gradient
    of the deterministic F_d x and y with respect to the image's pixels, |dF_x/dI| + |dF_y/dI| (80, 80),
    as Simonyan et al. (2014) map a classifier's saliency. Zeros for a policy without an image."""
    if act.encoder.image is None:
        return np.zeros(obs["image"].shape[-2:], np.float32)
    o = {k: torch.as_tensor(v[None]) for k, v in obs.items()}
    o["image"] = o["image"].float().requires_grad_(True)            # the encoder divides by 255 itself
    a = act.actor(act.encoder(o), deterministic=True, with_logp=False)[0][0]
    grads = [torch.autograd.grad(a[i], o["image"], retain_graph=True)[0][0, 0].abs() for i in (0, 1)]
    return (grads[0] + grads[1]).numpy()


def record_episode(run, error_mm=10.0, seed=0):
    """One evaluation episode of a run's policy, recorded per step for Fig. 16 (figures.plot_behaviour):
    the image and its saliency, the image features, X - X_g, the wrench, the action and the phase (0 free
    motion, 1 search after contact, 2 insertion). Returns (record, success)."""
    cfg = run["cfg"]
    act = load_policy(run)
    rec = {k: [] for k in ("image", "saliency", "image_features", "goal_offset", "f_world", "action", "phase")}

    def policy_step(obs):                       # the policy, recording what it sees, where it looks and what it does
        with torch.no_grad():
            img = torch.as_tensor(obs["image"][None])
            rec["image_features"].append(act.encoder.image(img)[0].numpy() if act.encoder.image is not None
                                         else np.zeros(6))
        rec["image"].append(obs["image"][0].copy())                       # (80, 80)
        rec["saliency"].append(saliency(act, obs))
        rec["action"].append(act(obs))
        return rec["action"][-1]

    def on_step(obs, r, info):
        rec["goal_offset"].append(info["goal_offset"])
        rec["f_world"].append(info["f_world"])
        rec["phase"].append(2 if info["depth"] > 0.001 else 1 if np.abs(info["f_world"][:3]).max() > 0.5 else 0)
    with evaluate.eval_env(cfg["task"], act, roi=cfg["roi"], e_r_mm=error_mm) as env:
        term, _, _ = sim.run_episode(env, policy_step, seed=evaluate.EVAL_SEED * 7 + seed, on_step=on_step)
    rec["phase"] = np.maximum.accumulate(rec["phase"])        # free -> search after contact -> insertion
    return rec, bool(term)


def match_runs(patterns):
    """The run directories (config.json + metrics.csv) that comma-separated glob patterns match."""
    dirs = sorted({d for p in patterns.split(",") for d in glob.glob(p.strip())
                   if all(os.path.exists(os.path.join(d, f)) for f in ("config.json", "metrics.csv"))})
    if not dirs:
        raise ArgError(f"{patterns!r}: no run directory (config.json + metrics.csv) matches")
    return dirs


def same_file(a, b):
    with open(a, "rb") as fa, open(b, "rb") as fb:
        return fa.read() == fb.read()


def same_run(d, to):
    """'same' when the archive `to` holds run d, 'earlier' when it holds d as it was before it was extended
    (--resume --train-episodes: the same config but for what a resume may set and where it lives, its
    metrics a prefix of d's), else None (another run, or a damaged archive)."""
    if all(os.path.exists(os.path.join(to, f)) and same_file(os.path.join(d, f), os.path.join(to, f))
           for f in ("config.json", "metrics.csv", "policy.pt")):
        return "same"
    cfgs, rows = [], []
    try:
        for x in (d, to):
            cfgs.append({k: v for k, v in read_config(x).items()                 # (flags added since: defaults)
                         if k not in (*command.RESUME_MAY_SET, "run_dir")})        # (a run dir may move)
            with open(os.path.join(x, "metrics.csv")) as f:
                rows.append(list(csv.DictReader(f)))
    except (OSError, ValueError, TypeError, AttributeError):
        return None
    return "earlier" if cfgs[0] == cfgs[1] and 0 < len(rows[1]) < len(rows[0]) and rows[0][:len(rows[1])] == rows[1] \
        else None


def archive_runs(patterns, dest=RESULTS_DIR, log=print):
    """Copy what the report reads of each finished run (eval.json written) to dest/<run name>/: under
    1 MB a run (policy.pt), where the checkpoint and the replay buffer that stay behind are hundreds of MB.
    A run dir lives on one machine; the archive travels with the repository, so the report can be
    regenerated from a fresh clone. A run already archived gets what it has new (the report's cached
    evaluations), a run extended since replaces its earlier state (what the run dir no longer holds goes:
    it set its old policy's files aside as *-epN.*); a different run under the same name is refused,
    before anything is copied. Returns the archived directories."""
    cli.check_dir_writable(dest, "--to")
    plan = []
    for d in match_runs(patterns):
        if not os.path.exists(os.path.join(d, "eval.json")):
            log(f"  {d}: not finished (no eval.json), not archived")
            continue
        to = os.path.join(dest, os.path.basename(os.path.normpath(d)))
        state = same_run(d, to) if os.path.exists(to) else "new"
        if state is None:
            raise ArgError(f"{to!r} holds another run than {d!r}: nothing archived (remove it, or rename the run dir)")
        plan.append((d, to, state))
    if not plan:
        raise ArgError(f"{patterns!r}: no finished run (with eval.json) to archive")
    kept = lambda names: [f for f in names if f in ARCHIVED or rundir.is_evaluation(f)]  # noqa: E731
    for d, to, state in plan:
        os.makedirs(to, exist_ok=True)
        names = kept(os.listdir(d))
        for f in set(kept(os.listdir(to))) - set(names) if state == "earlier" else ():
            os.remove(os.path.join(to, f))
        for f in names:
            shutil.copy2(os.path.join(d, f), os.path.join(to, f))
        log(f"  {d} -> {to}{' (extended since)' * (state == 'earlier')} ({', '.join(sorted(names))})")
    return [to for _, to, _ in plan]


def world_of(runs, patterns):
    """The one world the finished runs were made in (None: before the world had a version, issue 21's);
    ArgError where they are of two: their rows cannot share a table."""
    worlds = {r["eval"].get("world") for r in runs if r["eval"]}
    if len(worlds) > 1:
        raise ArgError(f"{patterns!r}: runs of worlds {', '.join(sorted(str(w or 'unversioned') for w in worlds))}; "
                       "one world per report (archive each world's runs apart)")
    return worlds.pop() if worlds else sim.WORLD


def read_notes(path):
    """docs/results-notes.md, the hand-written reading of the numbers, as {section title: text}: the text before
    the first '## ' line under '', each section under its title. The report puts a section beside the table it
    is titled after ('Table 1', 'Table 2', 'The ablations', 'Fig. 9, gear', 'Fig. 12, peg', ...) and the rest at the
    end."""
    if not os.path.exists(path):
        return {}
    with open(path) as f:
        parts = ("\n" + f.read()).split("\n## ")
    return {"": parts[0].strip(), **{p.split("\n", 1)[0].strip(): p.partition("\n")[2].strip() for p in parts[1:]}}


def note(notes, title):
    """The lines of a section of the notes (taken out of them), for under its table."""
    text = notes.pop(title, "")
    return ["", text] if text else []


def paper_sr_ct(paper):
    """PAPER_TABLE1's cell without the forces: 'SR, CT', or what it says instead."""
    return ", ".join(paper.split(", ")[:2])


def write_report(patterns, out_dir="docs", log=print, readme=None):
    """docs/RESULTS.md and its figures from run directories (glob patterns, comma-separated), all of one world."""
    cli.check_dir_writable(out_dir, "--out")
    runs = [load_run(d) for d in match_runs(patterns)]
    world = world_of(runs, patterns)
    os.makedirs(out_dir, exist_ok=True)
    for f in os.listdir(out_dir):          # an earlier report's figures, which these runs may not redraw
        if f.startswith("fig-") and f.endswith(".png"):
            os.remove(os.path.join(out_dir, f))
    notes = read_notes(os.path.join(out_dir, "results-notes.md"))
    command = "python tools/report.py" + ("" if patterns == REPORT_RUNS else f" \"{patterns}\"")
    md = ["# Results", "", f"Regenerated by `{command}` from {len(runs)} run directories, all made in "
          + (f"world {world} ({sim.WORLD_WHAT})" if world == sim.WORLD else f"world {world or 'unversioned'}") + ". "
          "Every number below was measured by running this code on a 2-core CPU machine; "
          "the paper's numbers stand beside ours. How the world and the method came to be as they are, "
          "and what each change did to the results, is told in [HISTORY.md](HISTORY.md).", "", "## The runs", "",
          "| run | command | method | episodes | minutes (threads) | final E_r (mm) | max E_r (mm) | eval SR "
          "5/10/15/20 mm |",
          "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        ev = r["eval"]
        srs = " / ".join(f"{row['success_rate']:.2f}" for row in ev["rows"]) if ev else "not finished"
        if ev and tuple(row["error_mm"] for row in ev["rows"]) != LEVELS:   # e.g. a 30 mm run's 10/20/30
            srs += " (at " + "/".join(f"{row['error_mm']:g}" for row in ev["rows"]) + " mm)"
        md.append(f"| `{r['dir']}` | `{command_of(r['cfg'])}` | {method_of(r['cfg'])} | "
                  f"{len(r['m']['episode'])} | {r['m']['elapsed_s'][-1] / 60:.1f} "
                  f"({r['cfg'].get('threads') or 'all'}) | "
                  f"{r['m']['e_r_mm'][-1]:.1f} | {r['m']['e_r_mm'].max():.1f} | {srs} |")
    # -- Table 1: peg at 20 mm, every learned row after the paper's budget
    md += ["", "## Table 1: peg-in-hole at 20 mm error", "",
           f"Every learned row trained {FAMILIES['methods'][3]} episodes (`--train-episodes {FAMILIES['methods'][3]} "
           "--stop-held 0`), as "
           "the paper's; 20 trials a seed on evaluation seeds never used in training. SR and CT: the mean over seeds "
           "and its 95 % bootstrap interval, as the paper's (Sec. 5.1.5), of the seeds' success rates and of their "
           "mean completion times (s; over the seeds with a success, their number in brackets where fewer); force "
           "and reward: the means of theirs (peak contact force per axis, N). The two-step baseline has no seeds: "
           "mean +- std over its trials. A run trained otherwise is not in this table.", "",
           "| method | seeds | SR | CT (s) | peak contact force x / y / z (N) | cumulative reward | "
           "paper: SR, CT, force x/y/z |", "|---|---|---|---|---|---|---|"]
    path = os.path.join(out_dir, "two-step-peg-20mm.json")     # the two-step row, kept with its world
    ts_world, ts_row = read_world_cache(path)
    ts_row = ts_row if ts_row and ts_world == world else None
    if ts_row is None and world == sim.WORLD:
        log("evaluating the two-step baseline (peg, 20 mm, 20 episodes)")
        with sim.AssemblyEnv("peg", e_r=0.02) as env:
            ts_row = evaluate.evaluate(env, baselines.make("two-step", env), 20, evaluate.EVAL_SEED,
                                       log=lambda *_: None)
        write_world_cache(path, world, ts_row)
    table1 = [("two-step", [ts_row] if ts_row else [], "-")]
    for name in [n + critics for n in LEARNED for critics in ("", PAPER_CRITICS)]:
        done = [r for r in runs if r["cfg"]["task"] == "peg" and method_of(r["cfg"]) == name and r["eval"]
                and fam_of(r).get("methods")]
        rows = [row for r in done for row in r["eval"]["rows"] if row["error_mm"] == 20.0]
        if done or not name.endswith(PAPER_CRITICS):      # a row with the paper's critics: only where it was run
            table1.append((name, rows, ", ".join(str(r["cfg"]["seed"]) for r in done)))
    readme_rows, srs = [], {}
    for name, rows, seeds in table1:
        base = name[:-len(PAPER_CRITICS)] if name.endswith(PAPER_CRITICS) else name
        label = TABLE1_ROWS[base] + (", the paper's critics" if base != name else "")
        critics = "-" if name == "two-step" else "the paper's" if base != name else "privileged"
        paper = PAPER_TABLE1[base]
        if not rows:
            md.append(f"| {label} | | not run in this world | | | | {paper} |")
            readme_rows.append(f"| {label} | {critics} | not run in this world | | {paper_sr_ct(paper)} |")
            continue
        over = lambda k: np.array([x[k][0] for x in rows if x[k]])     # noqa: E731  (each seed's mean)
        sr, ct = np.array([x["success_rate"] for x in rows]), over("completion_time_s")
        srs[name] = sr
        ct_cell = cell(rows[0], "completion_time_s") if len(rows) == 1 else ci(ct) + (
            f" ({len(ct)} seed{'s' * (len(ct) > 1)})" if 0 < len(ct) < len(rows) else "")
        fx = " / ".join(f"{over(f'contact_force_{a}_N').mean():.2f}" for a in "xyz")
        md.append(f"| {label} | {seeds} | {ci(sr)} | {ct_cell} | {fx} | "
                  f"{over('cumulative_reward').mean():.1f} | {paper} |")
        so_far = f" ({len(rows)} seed{'s' * (len(rows) > 1)} so far)" if len(rows) < 3 and name != "two-step" else ""
        readme_rows.append(f"| {label} | {critics} | {ci(sr)}{so_far} | {ct_cell} | {paper_sr_ct(paper)} |")
    if readme:
        write_readme_sentences(readme, log, srs)
        write_readme_table(readme, README_TABLE1, ["| method | critics | SR | CT (s) | paper: SR, CT (s) |",
                                                   "|---|---|---|---|---|", *readme_rows], log)
    md += ["", ordering_sentence(srs)] + note(notes, "Table 1") + sb3_section()
    # -- Table 2: ours, trained as the quickstart trains, in the training context and two unseen ones
    md += ["", "## Table 2: our policy in the training context and two unseen ones", "",
           "Ours trained as the quickstart trains (stopped when learned), tested at another two places of the board, "
           "as the paper's two unseen contexts are (its Table 2, on the real robot): SR / CT (s) at each error, mean "
           "over seeds, 20 trials a seed. Their runs and every other context: [CONTEXTS.md](CONTEXTS.md).", "",
           "| task | context | seeds | 5 mm | 10 mm | 15 mm | 20 mm | paper SR (real robot) |",
           "|---|---|---|---|---|---|---|---|"]
    for task in ("peg", "gear"):
        ours = [r for r in runs if r["cfg"]["task"] == task and method_of(r["cfg"]) == "ours" and r["eval"]
                and not fam_of(r)]
        if not ours:
            md.append(f"| {task} | - | | not run in this world | | | | |")
            continue
        for ctx in ("train",) + UNSEEN:
            per_seed = [eval_cached(r, ctx, log=log) for r in ours]             # [seed][level]
            cts = [[rows[i]["completion_time_s"][0] for rows in per_seed if rows[i]["completion_time_s"]]
                  for i in range(len(LEVELS))]
            cells = [f"{np.mean([rows[i]['success_rate'] for rows in per_seed]):.2f} / {np.mean(cts[i]):.1f}"
                     for i in range(len(LEVELS))]
            md.append(f"| {task} | {TABLE2_LABELS[ctx]} | {len(ours)} | {' | '.join(cells)} | "
                      f"{PAPER_TABLE2.get((task, ctx), '-')} |")
    md += note(notes, "Table 2")
    # -- the ablations (Figs. 9-11): what has been run in this world, and how to run the rest
    md += ["", "## The ablations (the paper's Figs. 9-11, on the gear)", "",
           "Each row of an ablation trains for the same number of episodes, 3 seeds; the curves are under Figures."]
    for exp, what in ABLATIONS.items():
        planned = [sweep.config_of([*row, "--seed", str(s)]) for row in sweep.EXPERIMENTS[exp] for s in sweep.SEEDS]
        have = [r for r in runs if r["eval"] and any(is_planned(r, p) for p in planned)]
        md.append(f"- {what}: {len(have)} of {len(planned)} runs finished in this world" +
                  ("" if len(have) == len(planned) else f"; the rest: `python tools/sweep.py {exp} --seeds "
                                                        f"{','.join(map(str, sweep.SEEDS))}`, then "
                   f"`python tools/report.py --archive \"runs/{exp}/*\" --to results/{exp}`") + ".")
    md += note(notes, "The ablations")
    # -- the ablations in numbers (the paper's Figs. 9-11 are curves): a row a setting, over its seeds
    for task in ("peg", "gear"):
        for fam in ("obs", "curriculum", "roi"):
            table = ablation_table(runs, task, fam, log=log)
            if table:
                title = FAMILIES[fam][0]
                md += ["", f"## {title[0].upper() + title[1:]}, {task} (the paper's {FAMILIES[fam][2]}), in numbers",
                       "", ABLATION_STATS, ""]
                md += table + ["", PAPER_ABLATIONS[fam]] + note(notes, f"{FAMILIES[fam][2]}, {task}")
    # -- learning curves: one figure per comparison of the paper and task
    figs = []
    for task in ("peg", "gear"):
        groups = {}
        for r in runs:
            if r["cfg"]["task"] == task:
                groups.setdefault(method_of(r["cfg"]), []).append(r)
        if groups:                         # every run of the task, grouped by what it trained
            name = f"fig-{task}-runs.png"
            figures.plot_groups(groups, ("sr15", "e_r_mm"), os.path.join(out_dir, name), f"{task}: every run")
            figs.append((name, f"{task}: every run, grouped by method and setting"))
        for fam, (title, keys, paper_fig, _) in FAMILIES.items():
            groups = groups_of(runs, task, fam)
            if len(groups) < 2:            # one row alone is no comparison (the gear's ROI row without the others)
                continue
            name = f"fig-{task}-{fam}.png"
            figures.plot_groups(groups, keys, os.path.join(out_dir, name), f"{task}: {title}")
            figs.append((name, f"{task}, {title} (the paper's {paper_fig}), every row at the same budget: mean over "
                               "seeds, 95% bootstrap band where there are several"))
    # -- context generalization (Fig. 12): the gear's ROI ablation (the paper's), the peg's quickstart and its twin
    for task in ("peg", "gear"):
        md_fig, figs_fig = fig12(runs, task, out_dir, log)
        if md_fig:
            md += md_fig + note(notes, f"Fig. 12, {task}")
            figs += figs_fig
    ours_peg = [r for r in runs if r["cfg"]["task"] == "peg" and method_of(r["cfg"]) == "ours" and r["eval"]]
    ours_peg = [r for r in ours_peg if not fam_of(r)] or ours_peg     # the quickstart's (stopped when learned) first
    if ours_peg and world != sim.WORLD:     # an episode recorded now would be this code's world, not the runs'
        md += ["", f"Fig. 16 (one episode's behaviour) is recorded by this code, of world {sim.WORLD}: not drawn for "
               "runs of an older world."]
    elif ours_peg:
        rec, term = record_episode(ours_peg[0], error_mm=10.0)
        figures.plot_behaviour(rec, os.path.join(out_dir, "fig-behaviour.png"),
                               f"one episode, peg, 10 mm error range, success {term}")
        figs.append(("fig-behaviour.png", "one episode of our peg policy at 10 mm error (the paper's Fig. 16)"))
    md += ["", "## Figures", ""]
    for name, caption in figs:
        md += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    md += ["", notes.pop("", "")] + [f"## {title}\n\n{text}" for title, text in notes.items()]   # what no table took
    with open(os.path.join(out_dir, "RESULTS.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    log(f"wrote {out_dir}/RESULTS.md and {len(figs)} figures")
    return 0


# ---------------------------------------------------------------- context generalization (Sec. 5.1.4, Fig. 12)
FAMILY_MM = 20.0                       # the error range the families are tested at
FAMILY_WHAT = {"place": "the board 12-32 cm from training's place, turned up to 0.5 rad",
               "light": "light from any side 35-85 deg high, 2700-7500 K, ambient 0.3-0.8 and diffuse 0.15-0.5 "
                        "(TinyRenderer's own: 0.6, 0.35)",
               "colour": "table and board of any hue, saturation up to 0.6, value 0.12-0.9 (table), 0.25-0.95 (board)",
               "parts": "1-4 small parts (nut, screw, washer, block, tie end) on the board beyond the tool's reach, "
                        "some inside the task ROI at large errors",
               "objects": "1-4 workbench objects (fixtures, clamps, blocks) 1-4 cm across and 0.5-3 cm tall on the "
                          "board, "
                          "3-7 cm from the axis beyond the tool's reach, some in the task ROI, some hiding part of "
                          "the board",
               "touch": "the part's sliding friction 0.10-0.70 (oiled to dry steel), clearance 0.05-0.3 mm, the board "
                        "tilted up to 1 deg",
               "mixed": "the five seen families together (place, light, colour, parts, objects)"}
GOAL_SR15, GOAL_DROP20 = 0.9, 0.1      # issue 22's goal: SR >= 0.9 at 15 mm, within 0.1 of training's at 20 mm


def goal_applies(ctx):
    """The goal holds the task-attention policy to every other place of the board and to backgrounds whose
    objects stay outside the task ROI; objects on the board, light and colour change what the ROI shows."""
    c = contexts.CONTEXTS[ctx]
    return ctx.startswith("loc-") or (c.objects and not c.on_board)


def context_change(name):
    """One line on what a context changes against training's."""
    c, t = contexts.CONTEXTS[name], contexts.CONTEXTS["train"]
    what = []
    if (c.board_xy, c.board_yaw) != (t.board_xy, t.board_yaw):
        what.append(f"the board {100 * np.hypot(*np.subtract(c.board_xy, t.board_xy)):.0f} cm away, turned "
                    f"{c.board_yaw - t.board_yaw:+.2f} rad")
    if c.objects:
        what.append(f"{len(c.objects)} objects " + ("on the board, inside the task ROI" if c.on_board else
                                                    "beside the board, outside the task ROI at every error"))
    if c.light != t.light:
        what.append("another light: " + ", ".join(f"{k} {v}" for k, v in c.light))
    if (c.table_rgba, c.board_rgba) != (t.table_rgba, t.board_rgba):
        what.append(f"table colour {c.table_rgba[:3]}, board {c.board_rgba[:3]}")
    return "; ".join(what) or "the training scene"


def context_rows(job, log=None):
    """One (run dir, context, levels, episodes) evaluation, cached in the run dir under the context's definition
    and the world's version (a context redefined, or another world, is evaluated again). Runs in a worker."""
    d, ctx, levels, episodes = job
    torch.set_num_threads(1)
    task = read_json(os.path.join(d, "config.json"))["task"]
    key = {"world": sim.WORLD, "context": contexts.context_key(ctx, task), "levels": list(levels), "episodes": episodes}
    path = os.path.join(d, f"eval-ctx-{ctx.replace(':', '-')}.json")
    cached = read_json(path) if os.path.exists(path) else {}
    if {k: v for k, v in cached.items() if k != "rows"} == key:
        return cached["rows"]
    if log:
        log(f"  evaluating {d} in {ctx} at {', '.join(f'{mm:g}' for mm in levels)} mm")
    run = load_run(d)
    cfg, act = run["cfg"], load_policy(run)
    with evaluate.eval_env(cfg["task"], act, ctx, cfg["roi"], cfg["clearance_mm"]) as env:
        rows = evaluate.evaluate_levels(env, act, levels, episodes, evaluate.EVAL_SEED + cfg["seed"])
    with open(path, "w") as f:
        json.dump({**key, "rows": rows}, f, indent=2)
    return rows


def training_of(run):
    """'seed S: N episodes', and where a run trained on since (rundir.set_aside) had first finished."""
    stops = rundir.set_aside_at(run["dir"])
    return (f"seed {run['cfg']['seed']}: {run['eval']['train_episodes']} episodes"
            + (f" (first finished at {stops[0]}, then trained on)" if stops else ""))


def ours_runs(patterns, out_dir):
    """The finished runs of ours (task attention) and of its full view made in this world, trained in 'train'."""
    cli.check_dir_writable(out_dir, "--out")
    runs = [load_run(d) for d in match_runs(patterns)]
    os.makedirs(out_dir, exist_ok=True)
    runs = [r for r in runs if r["eval"] and r["eval"].get("world") == sim.WORLD and r["cfg"]["roi"] in VIEWS
            and view_of(r["cfg"]) and r["cfg"]["context"] == "train"]
    if not runs:
        raise ArgError(f"{patterns!r}: no finished run of ours or its full view made in this world (world {sim.WORLD})")
    return runs


def view_of(cfg):
    """'task attention' or 'full view', with any other learning setting; '' for a run that is not ours."""
    setting = method_of({**cfg, "roi": "task", "error_mm": 20.0})
    return VIEWS.get(cfg["roi"], "") + setting[len("ours"):] if setting.startswith("ours") else ""


# the view of the robust option's runs, as `python tools/sweep.py option` makes them (sweep.OPTION, 600 episodes)
OPTION_VIEW = view_of(asdict(sweep.config_of(sweep.FLAGS(sweep.OPTION))))
# and of its leave-one-out (`python tools/sweep.py option-loo`): each view -> the part of the option it leaves out
LOO_VIEWS = {view_of(asdict(sweep.config_of(flags))): out for out, flags in sweep.leave_one_out().items()}


def evaluate_jobs(jobs_list, jobs):
    """context_rows of each job, in `jobs` processes (spawned: one torch thread each)."""
    if jobs == 1:
        return [context_rows(j) for j in jobs_list]
    import concurrent.futures as cf
    import multiprocessing as mp
    with cf.ProcessPoolExecutor(jobs, mp_context=mp.get_context("spawn")) as ex:
        return list(ex.map(context_rows, jobs_list))


def family_section(runs, episodes, jobs, log, readme=None):
    """The table of SR at FAMILY_MM per family of scenes (held-out seeds), each run's training column from its
    eval.json (the same seeds and code), as markdown lines; with readme, that file's table of them too."""
    jobs_list = [(r["dir"], f"{family}:test", (FAMILY_MM,), episodes) for r in runs for family in sim.FAMILIES]
    log(f"  {len(runs)} runs x {len(sim.FAMILIES)} families at {FAMILY_MM:g} mm, {len(jobs_list) * episodes} episodes "
        f"in {jobs} processes (cached ones are read back)")
    families = {}              # (task, view) -> {'train' or a family: [SR at FAMILY_MM of each seed]}
    for r in runs:
        families.setdefault((r["cfg"]["task"], view_of(r["cfg"])), {}).setdefault("train", []).extend(
            x["success_rate"] for x in r["eval"]["rows"] if x["error_mm"] == FAMILY_MM)
    for (d, ctx, _, _), rows in zip(jobs_list, evaluate_jobs(jobs_list, jobs)):
        r = next(r for r in runs if r["dir"] == d)
        by_family = families[(r["cfg"]["task"], view_of(r["cfg"]))]
        by_family.setdefault(contexts.held_out_family(ctx), []).append(rows[0]["success_rate"])
    md = family_table(families, episodes)
    if readme:
        write_readme_families(families, readme, log)
    return md + ["", "The families (ranges in `contexts.py`, ours): " + "; ".join(f"`{f}`: {FAMILY_WHAT[f]}"
                                                                               for f in sim.FAMILIES) + "."]


def family_table(families, episodes):
    """family_section's markdown: a row per (task, view) of families, {(task, view): {'train' or a family: [SR of
    each seed]}}; the option's leave-one-out (LOO_VIEWS) in a table of its own, beside the option."""
    md = [f"Each family (`contexts.FAMILIES`) draws a scene from a seed; each of the {episodes} trials of a run meets "
          "a scene of its own, from seeds that training never draws (`--context FAMILY:test`). Success rate at "
          f"{FAMILY_MM:g} mm, mean over seeds (min-max); train: the run's eval.json (the same evaluation seeds).", "",
          "| task | view | seeds | train | " + " | ".join(sim.FAMILIES) + " |", "|---" * (4 + len(sim.FAMILIES)) + "|"]
    cell = lambda x: (f"{np.mean(x):.2f} ({min(x):.2f}-{max(x):.2f})" if len(x) > 1  # noqa: E731
                      else f"{x[0]:.2f}" if x else "-")
    order = lambda kv: (kv[0][0], not kv[0][1].startswith(VIEWS["task"]), kv[0][1])   # noqa: E731
    row = lambda by_family: (f"{len(by_family[sim.FAMILIES[0]])} | {cell(by_family.get('train', []))} | "  # noqa: E731
                             + " | ".join(cell(by_family.get(f, [])) for f in sim.FAMILIES) + " |")
    for (task, view), by_family in sorted(families.items(), key=order):
        if view not in LOO_VIEWS:
            md.append(f"| {task} | {view} | {row(by_family)}")
    loo_tasks = sorted({task for task, view in families if view in LOO_VIEWS})
    if loo_tasks:
        md += ["", "What each part of the robust option gives: the option (`python tools/sweep.py option`) and the "
               "option with one part left out (`python tools/sweep.py option-loo`), the rest unchanged; the same "
               "cells as above, over the seeds each has run (the leave-one-out starts with seed 0). `mixed` draws "
               "place, light, colour, parts and objects together, so a family left out of `--randomize` still "
               "comes, more rarely, in mixed's scenes; left out with it, it would not.", "",
               "| task | left out | seeds | train | " + " | ".join(sim.FAMILIES) + " |",
               "|---" * (4 + len(sim.FAMILIES)) + "|"]
        for task in loo_tasks:
            if (task, OPTION_VIEW) in families:
                md.append(f"| {task} | nothing (the option) | {row(families[(task, OPTION_VIEW)])}")
            md += [f"| {task} | `{out}` | {row(families[(task, view)])}"
                   for view, out in LOO_VIEWS.items() if (task, view) in families]
    return md


README_FAMILIES = "Held-out scenes drawn from families"      # the README's captions of the tables the report makes
README_TABLE1 = "Table 1 in today's world"
README_CONTEXTS = "Trained in `train`, tested in each context"
QUICKSTART_RUNS = f"{RESULTS_DIR}/speed/worker-s*"     # the quickstart's reference runs: its command, seeds 0-2
QUICKSTART = re.compile(r"seeds\s+\d+-\d+\s+stopped\s+after\s.*?\sat\s+20\s+mm", re.S)   # its README sentence


ORDERING = re.compile(r"Under\s+the\s+paper's\s+critics,.*?under\s+its\s+own\s+critics:.*?\.(?=\s|$)", re.S)  # README


def ordering_sentence(srs):
    """Whether the paper's Table 1 order (ours above keypoint RL, both above visual and vanilla RL, which did not
    learn) holds among the rows with the paper's critics; srs: Table 1's row name -> its seeds' SR at 20 mm. One
    row is above another where its interval lies wholly above the other's."""
    have = [n for n in ("ours", "keypoint", "visual", "vanilla") if n + PAPER_CRITICS in srs]
    if not have:
        return ("Under the paper's critics, no row of Table 1 is run in this world. The paper's order under its own "
                "critics: not known.")
    got = {n: srs[n + PAPER_CRITICS] for n in have}                   # each row's seeds' SR
    stats = {n: mean_ci(v) if len(v) > 1 else [float(v[0])] * 3 for n, v in got.items()}
    name = lambda n: "ours" if n == "ours" else TABLE1_ROWS[n].split(" (")[0]        # noqa: E731
    said = ", ".join(f"{name(n)} {ci(v)}" + (f" ({len(v)} seed{'s' * (len(v) > 1)} so far)" if len(v) < 3 else "")
                     for n, v in got.items())
    pairs = [(a, b) for a, b in (("ours", "keypoint"), ("ours", "visual"), ("ours", "vanilla"),
                                 ("keypoint", "visual"), ("keypoint", "vanilla")) if a in have and b in have]
    above = [(a, b) for a, b in pairs if stats[a][1] > stats[b][2]]
    short = [f"{name(a)} is {'above' if stats[a][0] > stats[b][0] else 'not above'} {name(b)} "
             f"{'on the mean only (their intervals overlap)' if stats[a][0] > stats[b][0] else 'even on the mean'}"
             for a, b in pairs if (a, b) not in above]
    missing = [name(n) for n in ("ours", "keypoint", "visual", "vanilla") if n not in have]
    verdict = ("it holds" if not short and not missing else "not shown, as " + "; ".join(
        short + ([f"{' and '.join(missing)} {'is' if len(missing) == 1 else 'are'} not run yet"] if missing else [])))
    return (f"Under the paper's critics, SR at 20 mm (mean over seeds, 95 % interval): {said}. The paper's order, ours "
            f"above keypoint RL and both above visual and vanilla RL, under its own critics: {verdict}.")


def quickstart_sentence():
    """The README's sentence of what the quickstart's command gives, from its archived reference runs."""
    runs = sorted((load_run(d) for d in match_runs(QUICKSTART_RUNS)), key=lambda r: r["cfg"]["seed"])
    ev = [r["eval"] for r in runs]
    sr = [next(x["success_rate"] for x in e["rows"] if x["error_mm"] == 20.0) for e in ev]
    episodes, minutes = (", ".join(f"{e[k]:g}" for e in ev) for k in ("train_episodes", "train_minutes"))
    logs = [os.path.join(r["dir"], "train.log") for r in runs]
    walls = [re.search(r"([\d.]+) s wall\s*$", open(p).read()) if os.path.exists(p) else None for p in logs]
    wall = ", ".join(f"{float(w.group(1)) / 60:.1f}" for w in walls) + " min with the evaluation, " \
        if all(walls) else ""                                  # the console's last line, where /usr/bin/time wrote it
    return (f"seeds {runs[0]['cfg']['seed']}-{runs[-1]['cfg']['seed']} stopped after {episodes} episodes ({minutes} "
            f"min of training, {wall}[results/speed](results/speed), world {ev[0]['world']}) and insert "
            + ", ".join(f"{x:.2f}" for x in sr) + " at 20 mm")


SB3_RUNS = f"{RESULTS_DIR}/sb3/sb3-vs-ours-s*.json"    # bench/bench_sb3.py's results, one a seed
SB3 = re.compile(r"Stable-Baselines3's\s+SAC,\s+given\s.*?\sagainst\s+ours'.*?episodes", re.S)   # its README sentence


def sb3_results():
    """bench_sb3.py's archived results (SB3_RUNS), by seed."""
    return sorted((read_json(p) for p in glob.glob(SB3_RUNS)), key=lambda r: r["seed"])


def sb3_sentence():
    """The README's sentence of SB3's SAC beside ours in the same minutes, from bench_sb3.py's archived results."""
    res = sb3_results()
    if not res or {r.get("world") for r in res} != {sim.WORLD}:    # (one world: the sentence names it)
        raise ArgError(f"{SB3_RUNS}: no results of world {sim.WORLD} (python bench/bench_sb3.py --seed S, then copy "
                       "its json there)")
    said = lambda who, k, f="g": ", ".join(format(r[who][k], f) for r in res)  # noqa: E731
    return (f"Stable-Baselines3's SAC, given the same env, curriculum and minutes as ours (seeds "
            f"{', '.join(str(r['seed']) for r in res)}; {said('sb3', 'train_minutes', '.1f')} min; "
            f"[results/sb3](results/sb3), world {sim.WORLD}), inserts {said('sb3', 'sr20', '.2f')} at 20 mm after "
            f"{said('sb3', 'episodes')} episodes, against ours' {said('ours', 'sr20', '.2f')} after "
            f"{said('ours', 'episodes')} episodes")


def sb3_section():
    """RESULTS.md's lines on SB3's SAC beside ours in the same minutes (bench_sb3.py's archived results), if any."""
    res = [r for r in sb3_results() if r.get("world") == sim.WORLD]
    if not res:
        return []
    crit = lambda m: "not reached" if m is None else f"{m:.1f}"          # noqa: E731
    md = ["", "## Stable-Baselines3 beside ours, in the same minutes", "",
          "`python bench/bench_sb3.py --seed S --ours results/speed/halves-sS` (ours: the quickstart's runs of "
          "before the one-pass stop rule): SB3's SAC (`MultiInputPolicy`, its "
          "defaults, its CNN on the (1, 80, 80) image; a 50,000 replay buffer) on `tacrl/PegInsertion-v0` with our "
          "adaptive curriculum between episodes, trained for the minutes ours took, the machine to itself; then both "
          "greedy on the same 20 held-out episodes at 20 mm. To criterion: the minutes until the training curve held "
          "20 mm for 30 episodes with a success rate over the last 15 of 0.9 or more.", "",
          "| seed | minutes | ours: episodes | ours: to criterion (min) | ours: SR at 20 mm | SB3: episodes | "
          "SB3: final E_r (mm) | SB3: to criterion (min) | SB3: SR at 20 mm |", "|---" * 9 + "|"]
    md += [f"| {r['seed']} | {r['sb3']['train_minutes']:.1f} | {r['ours']['episodes']} | "
           f"{crit(r['ours']['to_criterion'])} | {r['ours']['sr20']:.2f} | {r['sb3']['episodes']} | "
           f"{r['sb3']['final_e_r_mm']:g} | {crit(r['sb3']['to_criterion'])} | {r['sb3']['sr20']:.2f} |" for r in res]
    return md


README_SENTENCES = {"the quickstart's sentence": (QUICKSTART, lambda srs: quickstart_sentence()),   # the README's
                    "the SB3 sentence": (SB3, lambda srs: sb3_sentence()),                      # prose
                    "the ordering sentence": (ORDERING, ordering_sentence)}


def write_readme_sentences(path, log, srs):
    """The README's generated sentences (README_SENTENCES) made anew from the archived runs (srs: Table 1's row
    name -> its seeds' SR at 20 mm)."""
    with open(path) as f:
        text = f.read()
    for name, (pattern, make) in README_SENTENCES.items():
        if not pattern.search(text):
            raise ArgError(f"{path}: {name} is not there (pattern {pattern.pattern!r})")
        sentence = make(srs)
        text = pattern.sub(lambda _: sentence, text, count=1)
    with open(path, "w") as f:
        f.write(text)
    log(f"wrote {path}'s {' and '.join(README_SENTENCES)}")


README_BACKGROUNDS = {"bg-objects": "objects beside", "bg-on-board": "parts on board", "bg-light": "other light",
                      "bg-colour": "other colours"}


def write_readme_contexts(table, levels, path, log):
    """The README's contexts table, made anew under its caption from write_contexts' table ((task, view, context)
    -> each seed's rows at `levels`): task attention and the full view as trained by default, SR at 20 mm in
    training's scene, at the other places (the range of their means, at 15 and 20 mm), with each background (the
    mean and the worst seed's), and the cumulative reward in training's scene against the places'."""
    i15, i20 = list(levels).index(15.0), list(levels).index(20.0)
    places = [c for c in contexts.CONTEXTS if c.startswith("loc-")]
    sr = lambda k: np.array([[x["success_rate"] for x in rows] for rows in table[k]])   # noqa: E731  (seeds, levels)
    cr = lambda k: np.mean([np.mean([x["cumulative_reward"][0] for x in rows]) for rows in table[k]])   # noqa: E731
    rows = []
    for task in ("peg", "gear"):
        for view in (VIEWS["task"], VIEWS["full"]):
            if (task, view, "train") not in table:
                continue
            at = {c: sr((task, view, c)) for c in ("train", *places, *README_BACKGROUNDS)}
            span = lambda i: (f"{min(at[c][:, i].mean() for c in places):.2f}-"  # noqa: E731
                              f"{max(at[c][:, i].mean() for c in places):.2f}")
            worst = lambda c: f"{at[c][:, i20].mean():.2f} ({at[c][:, i20].min():.2f})"   # noqa: E731
            rewards = [cr((task, view, c)) for c in places]
            rows.append(f"| {task}, {view} | {len(at['train'])} | {worst('train')} | {span(i15)} / {span(i20)} | "
                        + " | ".join(worst(c) for c in README_BACKGROUNDS)
                        + f" | {cr((task, view, 'train')):.1f} -> {min(rewards):.1f}-{max(rewards):.1f} |")
    header = ("| policy, SR: mean (worst seed) | seeds | training | 4 other places, 15 / 20 mm | "
              + " | ".join(README_BACKGROUNDS.values()) + " | reward: training -> places |")
    write_readme_table(path, README_CONTEXTS, [header, "|---" * (5 + len(README_BACKGROUNDS)) + "|", *rows], log)


def table_span(lines, caption):
    """(start, end) of the first markdown table after the line that starts `caption`; None where no line does."""
    at = next((i for i, ln in enumerate(lines) if ln.startswith(caption)), None)
    if at is None:
        return None
    start = next((i for i in range(at, len(lines)) if lines[i].startswith("|")), len(lines))
    return start, next((i for i in range(start, len(lines)) if not lines[i].startswith("|")), len(lines))


def write_readme_table(path, caption, table, log):
    """A README's table (markdown lines) made anew in place: the first table after the line that starts `caption`;
    the rest of the file as it was."""
    with open(path) as f:
        lines = f.read().split("\n")
    span = table_span(lines, caption)
    if span is None:
        raise ArgError(f"{path}: no line starts {caption!r}, a table's caption")
    start, end = span
    with open(path, "w") as f:
        f.write("\n".join(lines[:start] + table + lines[end:]))
    log(f"wrote {path}'s table under {caption!r}")


def readme_table(path, caption):
    """The markdown lines of the first table after the line of `path` that starts `caption` ([] where none)."""
    with open(path) as f:
        lines = f.read().split("\n")
    start, end = table_span(lines, caption) or (0, 0)
    return lines[start:end]


def check_readme(path, log=print):
    """The README's generated tables (Table 1, the contexts', the families') against what the report makes of
    results/ now, in a temporary folder: Failed naming each that differs (typed, or results/ changed since)."""
    with tempfile.TemporaryDirectory() as tmp:
        copy, docs = os.path.join(tmp, "README.md"), os.path.join(tmp, "docs")
        shutil.copy(path, copy)
        os.makedirs(docs)
        cached = os.path.join(os.path.dirname(os.path.abspath(path)), "docs", "two-step-peg-20mm.json")
        if os.path.exists(cached):                  # the two-step row, as the report keeps it with its world
            shutil.copy(cached, docs)
        quiet = lambda *_: None                     # noqa: E731
        write_report(REPORT_RUNS, docs, log=quiet, readme=copy)
        write_contexts(CONTEXT_RUNS, docs, log=quiet, readme=copy)
        differ = [f"the table under {c!r}" for c in (README_TABLE1, README_CONTEXTS, README_FAMILIES)
                  if readme_table(path, c) != readme_table(copy, c)]
        for name, (pattern, _) in README_SENTENCES.items():
            said = []
            for p in (path, copy):
                with open(p) as f:
                    said.append(" ".join(pattern.search(f.read()).group(0).split()))
            differ += [name] if said[0] != said[1] else []
    if differ:
        raise cli.Failed(f"{path}: {' and '.join(differ)} {'is' if len(differ) == 1 else 'are'} not what the report "
                         f"makes of {RESULTS_DIR}/ now (python "
                         f"tools/report.py --readme {path}, and --contexts --readme {path}, make them anew)")
    log(f"{path}: {', '.join(README_SENTENCES)}, Table 1, the contexts' and the families' tables are the report's")


def write_readme_families(families, path, log):
    """The README's families table, made anew in place under its caption: task attention as trained by default and
    with the robust option (OPTION_VIEW), SR at FAMILY_MM, the mean over seeds and the worst seed's."""
    shown = [(k, v) for k, v in sorted(families.items()) if k[1] in (VIEWS["task"], OPTION_VIEW)]
    cell = lambda x: f"{np.mean(x):.2f} ({min(x):.2f})" if x else "-"      # noqa: E731
    table = ["| policy, mean (worst seed) | seeds | train | " + " | ".join(sim.FAMILIES) + " |",
             "|---" * (3 + len(sim.FAMILIES)) + "|"]
    table += [f"| {task}, {view} | {len(by[sim.FAMILIES[0]])} | {cell(by.get('train', []))} | "
              + " | ".join(cell(by.get(f, [])) for f in sim.FAMILIES) + " |" for (task, view), by in shown]
    write_readme_table(path, README_FAMILIES, table, log)


def write_families(patterns, out_dir, episodes=20, jobs=1, log=print, readme=None):
    """The families alone (no named context): out_dir/FAMILIES.md, for runs not yet in the contexts' report; with
    readme, that file's families table too."""
    runs = ours_runs(patterns, out_dir)
    md = ["# Families of scenes, held out", "", f"Made by `python tools/report.py --families \"{patterns}\"` "
          f"(world {sim.WORLD}).", ""] + family_section(runs, episodes, jobs, log, readme)
    with open(os.path.join(out_dir, "FAMILIES.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    log(f"wrote {out_dir}/FAMILIES.md")
    return 0


def write_contexts(patterns, out_dir, levels=LEVELS, episodes=20, jobs=1, log=print, readme=None):
    """Train in one context, test in all: every run of ours (task attention) and of its full-view twin made in
    this world, evaluated in every context of contexts.CONTEXTS at `levels` (mm), `episodes` trials each; writes
    out_dir/CONTEXTS.md with the table, the goal's check, Fig. 12 and each context's full and task views (with
    readme, that file's families table too)."""
    runs = ours_runs(patterns, out_dir)
    # a run trained in scenes drawn from the families (--randomize) has met light, colours and parts of the kinds
    # the named backgrounds show: it is tested on the families' held-out seeds alone
    named = [r for r in runs if not r["cfg"].get("randomize")]
    jobs_list = [(r["dir"], ctx, tuple(levels), episodes) for r in named for ctx in contexts.CONTEXTS]
    log(f"  {len(named)} runs x {len(contexts.CONTEXTS)} contexts, {len(jobs_list) * len(levels) * episodes} episodes "
        f"in {jobs} processes (cached ones are read back)")
    table, trained = {}, {}    # (task, view, context) -> [rows of each seed]; (task, view) -> its seeds' training
    for (d, ctx, _, _), rows in zip(jobs_list, evaluate_jobs(jobs_list, jobs)):
        r = next(r for r in runs if r["dir"] == d)
        table.setdefault((r["cfg"]["task"], view_of(r["cfg"]), ctx), []).append(rows)
    for r in runs:
        trained.setdefault((r["cfg"]["task"], view_of(r["cfg"])), []).append(training_of(r))
    md = ["# Context generalization: trained in `train`, tested in every context", "",
          f"Made by `python tools/report.py --contexts \"{patterns}\"`. Every context is defined in "
          "`contexts.CONTEXTS` "
          f"(world {sim.WORLD}); the figures below show what each looks like. Each cell: success rate, mean over "
          f"seeds (min-max), {episodes} trials per seed at each error range on held-out evaluation seeds; CR: the mean "
          "cumulative reward over the ranges. Goal (task attention): SR >= 0.9 at 15 mm and within 0.1 of training's "
          "at 20 mm, at every other place and with every background whose objects stay outside the task ROI; "
          "checked on the mean over seeds, and (in brackets) seed by seed.", "",
          "| task | view | context | seeds | " + " | ".join(f"{mm:g} mm" for mm in levels) + " | CR | goal |",
          "|---" * (6 + len(levels)) + "|"]
    bars = {}
    order = lambda k: (k[0], not k[1].startswith(VIEWS["task"]), k[1],  # noqa: E731
                       list(contexts.CONTEXTS).index(k[2]))
    for task, view, ctx in sorted(table, key=order):          # task attention first, the contexts as defined
        seeds = table[(task, view, ctx)]
        sr = np.array([[x["success_rate"] for x in rows] for rows in seeds])          # (seeds, levels)
        cr = np.array([np.mean([x["cumulative_reward"][0] for x in rows]) for rows in seeds])
        bars.setdefault(task, {}).setdefault(view, {})[ctx] = mean_ci(cr)
        goal = "-"
        if view.startswith(VIEWS["task"]) and goal_applies(ctx) and 15.0 in levels and 20.0 in levels:
            train = np.array([[x["success_rate"] for x in rows] for rows in table[(task, view, "train")]])
            i15, i20 = list(levels).index(15.0), list(levels).index(20.0)
            met = lambda a, t: ((a[..., i15] >= GOAL_SR15)  # noqa: E731
                                & (t[..., i20] - a[..., i20] <= GOAL_DROP20 + 1e-9))
            goal = ("met" if met(sr.mean(0), train.mean(0)) else "**missed**") + \
                (f" ({int(met(sr, train).sum())} of {len(sr)} seeds)" if len(sr) > 1 else "")    # seed by seed
        cells = [f"{m:.2f} ({lo:.2f}-{hi:.2f})" if len(sr) > 1 else f"{m:.2f}"
                 for m, lo, hi in zip(sr.mean(0), sr.min(0), sr.max(0))]
        md.append(f"| {task} | {view} | {ctx} | {len(seeds)} | {' | '.join(cells)} | {cr.mean():.1f} | {goal} |")
    if readme and 15.0 in levels and 20.0 in levels:
        write_readme_contexts(table, levels, readme, log)
    md += ["", "## Families of scenes, held out", ""] + family_section(runs, episodes, jobs, log, readme)
    if len(named) < len(runs):
        md += ["", "A run trained with `--randomize` appears in the families alone: its training scenes were drawn "
                   "from the families, so the named backgrounds are of kinds it has seen; the families' held-out "
                   "seeds are its test."]
    md += ["", "Training (each run stops when learned, at most its --train-episodes; one trained on since, with "
           "`--resume DIR --train-episodes N --stop-held 0`, says where it had first finished):", ""]
    md += [f"- {task}, {view}: {', '.join(v)}" for (task, view), v in sorted(trained.items())]
    md += ["", "The contexts:", ""] + [f"- `{name}`: {context_change(name)}" for name in contexts.CONTEXTS]
    md += ["", PAPER_FIG12, ""]
    for task, by_view in bars.items():
        name = f"ctx-{task}-bars.png"
        figures.plot_context_bars(by_view, os.path.join(out_dir, name), f"{task}: trained in 'train', tested in each "
                                                                        "context")
        md += [f"![{task}: Fig. 12]({name})", "", f"*{task}: mean cumulative reward per context (bars: 95 % bootstrap "
               "interval over seeds), task attention against the full view (the paper's Fig. 12)*", ""]
    for task in sorted({t for t, _, _ in table}):
        name = f"ctx-{task}-views.png"
        figures.plot_views(task, ("full", "task"), tuple(contexts.CONTEXTS), os.path.join(out_dir, name))
        md += [f"![{task}: the contexts]({name})", "", f"*{task}: what the policy sees in each context at the start "
               "of the same episode, through the full view and the task-attention ROI*", ""]
    with open(os.path.join(out_dir, "CONTEXTS.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    log(f"wrote {out_dir}/CONTEXTS.md")
    return 0


def critics_kind(cfg):
    """What a run's critics read and learn from beyond the actor's observation (write_compare's column)."""
    if cfg["critic"] == "privileged":
        return "X - X_g an input"
    if cfg.get("aux_offset"):
        return "X - X_g a label"
    return "+ time, E_r, Ex_r" if cfg.get("critic_extra", True) else "the paper's"   # (study: where not today's)


def critics_cells(run_dir):
    """tools/critics.py's diagnostics of a run as two table cells ('-' where not made)."""
    path = os.path.join(run_dir, "critics.json")
    if not os.path.exists(path):
        return "- | -"
    c = read_json(path)
    q = c["q_vs_mc"]
    r2, r0 = c["probe"]["r2"], c["probe"]["r2_untrained"]
    return (f"{q['bias']:+.1f} ({q['corr']:.2f})" if q else "-") + \
        f" | {r2['x']:.2f} / {r2['y']:.2f} ({r0['x']:.2f} / {r0['y']:.2f})"


def write_compare(patterns, out_dir, name, log=print):
    """A comparison of learning settings (docs/CRITICS.md's runs): every run, finished or not, one row each
    (settings, seed, episodes, where the curriculum stood and when it first reached the final range, the
    evaluation, minutes), and their curves grouped by setting, to out_dir/<name>.md and <name>.png. Runs of
    two worlds are refused: their numbers cannot share a table."""
    cli.check_dir_writable(out_dir, "--out")
    runs = [load_run(d) for d in match_runs(patterns)]
    world = world_of(runs, patterns)     # (an unfinished run has no world of its own: it is read as of this one)
    os.makedirs(out_dir, exist_ok=True)
    md = [f"Made by `python tools/report.py \"{patterns}\" --compare {name}` (world {world}). E_r: where the "
          "curriculum stood at the last episode, the most it reached, and the first episode at the final range; "
          "SR on the held-out evaluation seeds (20 episodes a level); a run without an evaluation did not finish. "
          "Q - MC and the probe: `tools/critics.py`'s diagnostics on held-out episodes at the final range (its "
          "docstring says how; -: not made, Q's needs the run's checkpoint): Q's mean bias against the soft "
          "Monte-Carlo return and their correlation; the R^2 with which a linear probe of the critics' features "
          "(privileged runs: the actor's) predicts x and y of X - X_g, and in brackets the same encoder's "
          "untrained.", "",
          "Critics: what they read and learn from, beside the actor's observation: nothing (the paper's), what the "
          "agent knows besides it (the time, E_r and Ex_r, as `--critic multimodal` reads them), X - X_g as a label "
          "(`--aux-offset`), or X - X_g as an input (privileged). Settings: the flags that differ from today's "
          f"defaults; those of the critics study (issues 31 and 50) are on git tag {command.STUDY_TAG}.", "",
          "| settings | critics | seed | episodes | E_r last / max (mm) | first at final | eval SR " +
          " / ".join(f"{mm:g}" for mm in LEVELS) + " mm | minutes | Q - MC (corr) | probe R^2 x / y |",
          "|---" * 10 + "|"]
    groups = {}
    setting = lambda cfg: f"{cfg['task']}, " + method_of(cfg) + (  # noqa: E731  (a task's runs never share a row)
        " (privileged critics)" if cfg["critic"] == "privileged" else "")
    for r in sorted(runs, key=lambda r: (setting(r["cfg"]), r["cfg"]["seed"])):
        m, cfg = r["m"], r["cfg"]
        at_final = np.flatnonzero(m["e_r_mm"] >= cfg["error_mm"] - 1e-6)
        ev = r["eval"]
        sr = " / ".join(f"{x['success_rate']:.2f}" for x in ev["rows"]) if ev else "unfinished"
        minutes = ev["train_minutes"] if ev else m["elapsed_s"][-1] / 60
        md.append(f"| {setting(cfg)} | {critics_kind(cfg)} | {cfg['seed']} | {len(m['episode'])} | "
                  f"{m['e_r_mm'][-1]:.1f} / "
                  f"{m['e_r_mm'].max():.1f} | {int(m['episode'][at_final[0]]) if len(at_final) else '-'} | {sr} | "
                  f"{minutes:.1f} | {critics_cells(r['dir'])} |")
        groups.setdefault(setting(cfg), []).append(r)
    figures.plot_groups(groups, ("e_r_mm", "sr15"), os.path.join(out_dir, f"{name}.png"), f"{name}: curves by setting")
    md += ["", f"![{name}]({name}.png)", "", "*Curves by setting: mean over seeds (band: 95 % bootstrap over seeds).*"]
    with open(os.path.join(out_dir, f"{name}.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    log(f"wrote {out_dir}/{name}.md and {name}.png")
    return 0


def main(argv=None):
    ap = cli.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="?", help="comma-separated glob patterns of run directories (default: "
                                            f"{REPORT_RUNS}; "
                    f"with --contexts or --families, {CONTEXT_RUNS})")
    ap.add_argument("--archive", action="store_true", help="copy the finished runs' small files to --to instead")
    ap.add_argument("--to", default=RESULTS_DIR, help=f"where --archive copies to (default: {RESULTS_DIR})")
    ap.add_argument("--out", default="docs", help="where the report is written (default: docs)")
    ap.add_argument("--contexts", action="store_true", help="evaluate ours and its full view in every context "
                    "instead, to --out/CONTEXTS.md (Fig. 12)")
    ap.add_argument("--families", action="store_true", help="evaluate ours and its full view in the families of "
                    "scenes alone instead, to --out/FAMILIES.md")
    ap.add_argument("--compare", default="", metavar="NAME", help="a table and curves of the runs by learning setting "
                    "instead, to --out/NAME.md and NAME.png")
    ap.add_argument("--check-readme", default="", metavar="PATH", help="check that this README's generated tables "
                    "are what the report makes of the archived runs now, instead (exit 1 where not)")
    ap.add_argument("--jobs", type=int, default=1, help="processes for --contexts' evaluations (one torch thread each)")
    ap.add_argument("--readme", default="", metavar="PATH", help="also make this README's tables anew: Table 1 (under "
                    f"the line that starts {README_TABLE1!r}), or with --contexts or --families the families' (under "
                    f"{README_FAMILIES!r})")
    a = ap.parse_args(argv)
    if a.jobs < 1:
        raise ArgError(f"--jobs must be at least 1, not {a.jobs}")
    if a.runs is None and (a.archive or a.compare):
        raise ArgError(f"--{'archive' if a.archive else 'compare'} takes the run directories, e.g. \"runs/*\"")
    if a.archive:
        archive_runs(a.runs, a.to)
    elif a.compare:
        if not a.compare.replace("-", "").replace("_", "").isalnum():
            raise ArgError(f"--compare takes a file name of letters, digits, - and _, not {a.compare!r}")
        write_compare(a.runs, a.out, a.compare)
    elif a.check_readme:
        if not os.path.isfile(a.check_readme):
            raise ArgError(f"--check-readme {a.check_readme!r}: no such file")
        check_readme(a.check_readme)
    elif a.contexts:
        write_contexts(a.runs or CONTEXT_RUNS, a.out, jobs=a.jobs, readme=a.readme)
    elif a.families:
        write_families(a.runs or CONTEXT_RUNS, a.out, jobs=a.jobs, readme=a.readme)
    else:
        write_report(a.runs or REPORT_RUNS, a.out, readme=a.readme)


if __name__ == "__main__":
    sys.exit(cli.command("report", main))
