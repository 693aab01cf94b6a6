"""runs.py: the archived runs as the report reads them (tools/report.py). A run directory lives on the machine
that trained it (its checkpoint and replay are hundreds of MB); archive_runs copies what the report reads (under
1 MB a run) to results/, which the repository keeps, so that every table can be made again from a fresh clone.
Here: reading a run (load_run), naming what it trained (method_of, command_of) and which of the paper's
comparisons it is a row of (fam_of), its evaluations in other contexts (eval_cached, cached beside it), the mean
over seeds with its bootstrap interval (ci), and the archive itself.
"""
import csv
import glob
import json
import os
import shutil
from dataclasses import asdict, fields

import numpy as np
import torch

import cli
import command
import contexts
import evaluate
import figures
import rundir
import sim
import sweep
import tacrl
from cli import ArgError

RESULTS_DIR = "results"       # the archived runs the report is built from; the repository keeps them
ARCHIVED = ("config.json", "metrics.csv", "policy.pt", "curves.png", "train.log", "critics.json")    # and eval*.json
LEVELS = (5.0, 10.0, 15.0, 20.0)
MULTIMODAL = " (critic multimodal)"     # method_of's suffix for a run with multimodal critics (ours are privileged)
LEARNED = ("vanilla", "visual", "keypoint", "ours")
VIEWS = {"task": "task attention", "full": "full view"}       # the quickstart's view and its full-view twin
OBS_NAMES = {"pt": "P-T", "ts-pt": "Time-series P-T", "ts-ptv": "Time-series P-T-V"}
COMPARISONS = {   # the paper's: (title, curves, the paper's figure, the episodes each of its runs trains: its budget)
    "methods": ("ours against the learned baselines", ("return", "sr15", "e_r_mm"), "Table 1", 200),
    "obs": ("observation ablation: Ex_r held at 10 mm, E_r adaptive", ("return", "sr15", "e_r_mm"), "Fig. 9", 200),
    "curriculum": ("curriculum ablation", ("return", "sr15", "e_r_mm", "ex_r_mm"), "Fig. 10", 300),
    "roi": ("ROI ablation", ("return", "sr15", "e_r_mm"), "Fig. 11", 200),
}


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
    """A run's config as a dict of today's flags, in config.json's order, and of flags retired to a commit (the
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
    """A run's policy.pt (ArgError where it is not one, or is another task's). The archive keeps a policy.pt only
    where a command or the report uses it (results/README.md); git history holds the rest."""
    path = os.path.join(run["dir"], "policy.pt")
    if not os.path.exists(path):
        raise ArgError(f"{path}: no policy.pt (an archived run keeps one only where the README or the report uses it; "
                       f"`git checkout $(git rev-list -1 HEAD -- {path})^ -- {path}` brings an earlier one back)")
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
    default = command.preset_defaults(tacrl.Config, cfg)
    named = ("task", "seed", "context", "vanilla", "obs", "curriculum", "roi", "error_mm", "robust") + \
        command.NOT_LEARNING
    changed = [f"{k} {v}" for k, v in cfg.items()         # (a retired flag is in cfg only where not today's code)
               if k not in named and (not hasattr(default, k) or v != getattr(default, k))]
    changed = (["robust"] if cfg.get("robust") else []) + changed
    return name + (f" ({', '.join(changed)})" if changed else "")


def command_of(cfg):
    """The training command that reproduces a run: the flags whose values differ from the defaults (with the
    critics study's flags, the command of its commit)."""
    default, flags = command.preset_defaults(tacrl.Config, cfg), ["python tacrl.py"]
    for k, v in cfg.items():
        if k in ("run_dir", "threads", "device", "resume", "track"):
            continue
        if not hasattr(default, k) or v != getattr(default, k) or k == "task":        # (a retired flag: its tag's)
            value = "" if v is True else f" {v:g}" if isinstance(v, float) else f" {v}"
            flags.append(f"--{k.replace('_', '-')}" + value)
    return " ".join(flags)


def groups_of(runs, task, fam):
    """The rows of one of the paper's comparisons (COMPARISONS' fam) for a task: {row label: [its runs, a seed each]}."""
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
    """The paper's comparisons a run is a row of: families() where it trained the comparison's budget (COMPARISONS,
    --stop-held 0), as the paper's rows do. A run stopped when learned, as the quickstart's, or trained for another
    number of episodes, is a row of none (Table 2, Fig. 12 and docs/contexts.md take those)."""
    return {f: label for f, label in families(run["cfg"]).items() if trained_budget(run, COMPARISONS[f][3])}


def families(cfg):
    """The paper's comparisons a run takes part in: {figure family: curve label}. Only runs with
    the default learning settings (method_of without a suffix) are compared."""
    name = method_of(cfg)
    if name.endswith(MULTIMODAL) and name[:-len(MULTIMODAL)] in LEARNED:   # a row with the paper's critics
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


def context_rows(job, log=None):
    """One (run dir, context, levels, episodes[, optional]) evaluation, cached in the run dir under the context's
    definition and the world's version (a context redefined, or another world, is evaluated again). Runs in a worker.
    An optional one of a run whose policy.pt left the archive, not cached, is None (its cell stays empty)."""
    d, ctx, levels, episodes, *optional = job
    torch.set_num_threads(1)
    task = read_json(os.path.join(d, "config.json"))["task"]
    key = {"world": sim.WORLD, "context": contexts.context_key(ctx, task), "levels": list(levels), "episodes": episodes}
    path = os.path.join(d, f"eval-ctx-{ctx.replace(':', '-')}.json")
    cached = read_json(path) if os.path.exists(path) else {}
    if {k: v for k, v in cached.items() if k != "rows"} == key:
        return cached["rows"]
    if optional and optional[0] and not os.path.exists(os.path.join(d, "policy.pt")):
        return None
    if log:
        log(f"  evaluating {d} in {ctx} at {', '.join(f'{mm:g}' for mm in levels)} mm")
    run = load_run(d)
    cfg, act = run["cfg"], load_policy(run)
    with evaluate.eval_env(cfg["task"], act, ctx, cfg["roi"], cfg["clearance_mm"]) as env:
        rows = evaluate.evaluate_levels(env, act, levels, episodes, evaluate.EVAL_SEED + cfg["seed"])
    with open(path, "w") as f:
        json.dump({**key, "rows": rows}, f, indent=2)
    return rows


def evaluate_jobs(jobs_list, jobs, fn=None):
    """fn (default: context_rows) of each job, in `jobs` processes (spawned: one torch thread each)."""
    fn = fn or context_rows
    if jobs == 1:
        return [fn(j) for j in jobs_list]
    import concurrent.futures as cf
    import multiprocessing as mp
    with cf.ProcessPoolExecutor(jobs, mp_context=mp.get_context("spawn")) as ex:
        return list(ex.map(fn, jobs_list))


def view_of(cfg):
    """'task attention' or 'full view', with any other learning setting; '' for a run that is not ours."""
    setting = method_of({**cfg, "roi": "task", "error_mm": 20.0})
    return VIEWS.get(cfg["roi"], "") + setting[len("ours"):] if setting.startswith("ours") else ""


# the view of the robust option's runs, as `python tools/sweep.py option` makes them (sweep.OPTION, 600 episodes)
OPTION_VIEW = view_of(asdict(sweep.config_of(sweep.FLAGS(sweep.OPTION))))


# and of --robust's (`python tools/sweep.py robust-flag`)
ROBUST_VIEW = view_of(asdict(sweep.config_of(["--robust"])))


# and of its leave-one-out (`python tools/sweep.py option-loo`): each view -> the part of the option it leaves out
LOO_VIEWS = {view_of(asdict(sweep.config_of(flags))): out for out, flags in sweep.leave_one_out().items()}


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
