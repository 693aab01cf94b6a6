"""results.py: the paper's experiments re-made from the archived runs (Sec. 5.1.2-5.1.5), as the named blocks of
the pages that show them (pages.py): Table 1 (docs/table1.md, and the README's), Table 2 (table2.md), the
ablations of Figs. 9-11 in numbers (fig9-observations.md, fig10-curricula.md, fig11-roi.md), Fig. 12
(fig12-contexts.md), SB3 beside ours (sb3.md) and the README's findings; with their figures (fig-*.png, Fig. 16's
fig-behaviour.png). make() returns {block name: markdown}; tools/report.py writes them into the pages.

One rule compares two settings everywhere (above): A is above B where A's 95 % bootstrap interval over seeds lies
wholly above B's; where only the means are in that order, it says "on the mean only".
"""
import glob
import os
import re

import numpy as np
import torch

import baselines
import evaluate
import figures
import sim
import sweep
from cli import ArgError
from runs import (COMPARISONS, LEARNED, LEVELS, MULTIMODAL, RESULTS_DIR, VIEWS, ci, eval_cached, fam_of, families,
                  groups_of, is_planned, load_policy, load_run, match_runs, mean_ci, method_of, read_json,
                  read_world_cache, world_of, write_world_cache)

BLOCKS = ("table1", "readme-table1", "table2", "quickstart", "sb3", "readme-sb3", "fig9", "fig10", "fig11",
          "fig12-peg", "fig12-gear", "readme-findings")        # the pages' blocks that make() fills (pages.py)
# what the report reads by default: an experiment's runs lie in results/<experiment of tools/sweep.py>/
ABLATIONS = {"obs": "gear-obs", "curriculum": "gear-curriculum", "roi": "gear-roi"}   # comparison -> experiment
REPORT_RUNS = ",".join(f"{RESULTS_DIR}/{e}/*" for e in ("table1", "contexts", *ABLATIONS.values()))
QUICKSTART_RUNS = f"{RESULTS_DIR}/speed/worker-s*"     # the quickstart's reference runs: its command, seeds 0-2
SB3_RUNS = f"{RESULTS_DIR}/sb3/sb3-vs-ours-s*.json"    # bench/bench_sb3.py's results, one a seed

# The paper's numbers, next to which ours stand. Table 1: simulated peg, 20 test trials after 200 episodes.
PAPER_TABLE1 = {"two-step": "0.533, 19.00 +- 5.75, 13.21 / 13.22 / 9.78",
                "vanilla": "did not learn", "visual": "did not learn", "keypoint": "0.96, 4.27 +- 2.97, -",
                "ours": "1.00, 2.41 +- 1.93, 12.14 / 6.92 / 3.23"}
TABLE1_ROWS = {"vanilla": "vanilla RL (`--vanilla`: no base policy)", "visual": "visual RL (`--obs v`)",
               "keypoint": "keypoint RL (`--obs ts-ptk`)", "ours": "ours (TA-MRP + adaptive curriculum)",
               "two-step": "two-step (visual servo, spiral search)"}
# what a row's critics are: ours privileged; multimodal as the paper's, with what we added (README difference 13)
CRITICS = {"": "privileged (ours)", MULTIMODAL: "multimodal (ours)"}
# Table 2 (the paper's real robot), success rate at 5/10/15/20 mm: the rows that the paper's layout pins down
PAPER_TABLE2 = {("peg", "train"): "1.00 / 1.00 / 1.00 / 0.80", ("peg", "loc-1"): "1.00 / 1.00 / 0.90 / 0.75",
                ("gear", "train"): "1.00 / 1.00 / 0.95 / 0.70"}
UNSEEN = ("loc-1", "loc-2")        # our stand-ins for Table 2's 'unseen 1' and 'unseen 2': two other places
TABLE2_LABELS = {"train": "training context", "loc-1": "unseen 1 (`loc-1`)", "loc-2": "unseen 2 (`loc-2`)"}
# Fig. 12 as the paper made it (Sec. 5.1.4): the gear ROI ablation's ROI 300 against its full view (the paper's
# ROI-800), at four other table locations (scored by their mean) and with objects added to the background
FIG12_LOCATIONS, FIG12_BACKGROUND = ("loc-1", "loc-2", "loc-3", "loc-4"), "bg-objects"
FIG12_VIEWS = {"gear": {"300": "ROI 300", "full": "full view (ROI 800)"},       # the paper's: its ROI ablation
               "peg": VIEWS}                                                   # ours: the paper has no peg ablation
PAPER_FIG12 = ("The paper (simulation, the gear's ROI ablation, Fig. 12, average cumulative reward): ROI-300 61.19 -> "
               "54.73 (new background), 69.23 -> 46.46 (new locations); ROI-800, the full view, 61.12 -> -23.06 and "
               "59.51 -> -14.65.")
PAPER_ABLATIONS = {   # what the paper says of each ablation's curves (Sec. 5.1.4); it gives no numbers beside these
    "obs": "The paper (Fig. 9, gear, the final error range after 200 episodes): all three learn at 2 mm; P-T tolerates "
           "only 5 mm, time-series P-T more but limited, time-series P-T-V is robust under 10 mm.",
    "curriculum": "The paper (Fig. 10, gear, 300 episodes, training curves): without curriculum, 10 mm reaches SR 0.9 "
                  "and reward 70, 20 mm SR 0.6 and reward 20, 30 mm less; at 30 mm every curriculum beats no "
                  "curriculum, g2-c10 learns faster than g2-c30, and g2-c2 behaves like g2-c10.",
    "roi": "The paper (Fig. 11, gear, 200 episodes): ROI-100*160 reaches only 7 mm, as without vision; ROI-200*200 is "
           "robust in a limited range; ROI-300*300 and ROI-800*800 are robust in a larger range, the full view the "
           "fastest to converge.",
}
SEEDS_NOTE = ("mean over seeds [95 % bootstrap interval of that mean]; with 3 seeds the interval is close to the "
              "seeds' min-max")


def above(a, b):
    """The one rule for 'A above B' (values: one a seed): 'above' where A's 95 % interval over seeds lies wholly above
    B's, 'on the mean only' where only A's mean is above B's, else 'not above'."""
    sa, sb = (mean_ci(v) if len(v) > 1 else [float(v[0])] * 3 for v in (a, b))
    return "above" if sa[1] > sb[2] else "on the mean only" if sa[0] > sb[0] else "not above"


def listed(names):
    """'a', 'a and b', 'a, b and c'."""
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def verdicts(pairs):
    """[(name A, name B, above(A, B))] as one phrase, grouped: 'X is above B and C; X and Y are above D on the mean
    only'. A name may be a list of names, said together."""
    said, groups = [], {}
    for a, b, v in pairs:
        groups.setdefault((tuple(a) if isinstance(a, list) else (a,), v), []).append(b)
    for (a, v), bs in groups.items():
        said.append(f"{listed(a)} {'are' if len(a) > 1 else 'is'} {'not above' if v == 'not above' else 'above'} "
                    f"{listed(bs)}" + (" on the mean only" if v == "on the mean only" else ""))
    return "; ".join(said)


# ---------------------------------------------------------------- Table 1
def two_step_row(out_dir, world, log):
    """The two-step baseline's row (peg, 20 mm, 20 trials), kept with its world in out_dir; evaluated where none is."""
    path = os.path.join(out_dir, "two-step-peg-20mm.json")
    ts_world, row = read_world_cache(path)
    row = row if row and ts_world == world else None
    if row is None and world == sim.WORLD:
        log("evaluating the two-step baseline (peg, 20 mm, 20 episodes)")
        with sim.AssemblyEnv("peg", e_r=0.02) as env:
            row = evaluate.evaluate(env, baselines.make("two-step", env), 20, evaluate.EVAL_SEED, log=lambda *_: None)
        write_world_cache(path, world, row)
    return row


def paper_sr_ct(paper):
    """PAPER_TABLE1's cell without the forces: 'SR, CT', or what it says instead."""
    return ", ".join(paper.split(", ")[:2])


def table1(runs, ts_row):
    """Table 1 (docs/table1.md's), the README's shorter one, and {row name: its seeds' SR at 20 mm}: a row a method
    and critics, every learned row after the paper's budget of episodes."""
    budget = COMPARISONS["methods"][3]
    md = ["| method | critics | seeds | SR | CT (s) | peak contact force x / y / z (N) | cumulative reward | "
          "paper: SR, CT (s), force x / y / z (N) |", "|---" * 8 + "|"]
    readme = ["| method | critics | SR at 20 mm | CT (s) | paper: SR, CT (s) |", "|---|---|---|---|---|"]
    rows, srs = [("two-step", [ts_row] if ts_row else [], "-")], {}
    for name in [n + critics for n in LEARNED for critics in CRITICS]:
        done = [r for r in runs if r["cfg"]["task"] == "peg" and method_of(r["cfg"]) == name and r["eval"]
                and fam_of(r).get("methods")]
        if done or not name.endswith(MULTIMODAL):      # a row with multimodal critics: only where it was run
            rows.append((name, [x for r in done for x in r["eval"]["rows"] if x["error_mm"] == 20.0],
                         ", ".join(str(r["cfg"]["seed"]) for r in done)))
    for name, got, seeds in rows:
        base = name[:-len(MULTIMODAL)] if name.endswith(MULTIMODAL) else name
        critics = "-" if name == "two-step" else CRITICS[name[len(base):]]
        paper, label = PAPER_TABLE1[base], TABLE1_ROWS[base]
        if not got:
            md.append(f"| {label} | {critics} | | not run in this world | | | | {paper} |")
            readme.append(f"| {label} | {critics} | not run in this world | | {paper_sr_ct(paper)} |")
            continue
        over = lambda k: np.array([x[k][0] for x in got if x[k]])     # noqa: E731  (each seed's mean)
        sr, ct = np.array([x["success_rate"] for x in got]), over("completion_time_s")
        srs[name] = sr
        if len(got) == 1:                              # the two-step: mean +- std over its trials
            ct_cell = "-" if not got[0]["completion_time_s"] else "{:.2f} +- {:.2f}".format(*got[0]["completion_time_s"])
        else:
            ct_cell = ci(ct) + (f" ({len(ct)} seed{'s' * (len(ct) > 1)})" if 0 < len(ct) < len(got) else "")
        fx = " / ".join(f"{over(f'contact_force_{a}_N').mean():.2f}" for a in "xyz")
        md.append(f"| {label} | {critics} | {seeds} | {ci(sr)} | {ct_cell} | {fx} | "
                  f"{over('cumulative_reward').mean():.1f} | {paper} |")
        so_far = f" ({len(got)} seed{'s' * (len(got) > 1)} so far)" if len(got) < 3 and name != "two-step" else ""
        readme.append(f"| {label} | {critics} | {ci(sr)}{so_far} | {ct_cell} | {paper_sr_ct(paper)} |")
    note = ("Critics: privileged (ours) also read X - X_g; multimodal (ours) read what the actor reads, as the paper's "
            "do, and the time, the curriculum's E_r and Ex_r, with LayerNorms (README difference 13). "
            f"Every learned row trained {budget} episodes (`--train-episodes {budget} --stop-held 0`), as the paper's, "
            "and was tested in 20 trials a seed on seeds never used in training. SR: each seed's success rate over its "
            f"20 trials, {SEEDS_NOTE}. CT: each seed's mean completion time of its successful trials (s), the same "
            "statistic (over the seeds with a success, their number in brackets where fewer). Force (the peak of the "
            "0.2 s mean wrench per axis in a trial, N) and reward: the means over seeds of each seed's mean. The "
            "two-step baseline has no seeds: mean +- std over its 20 trials. The paper's: SR over 20 trials, CT mean "
            "+- std.")
    return [note, "", *md], readme, srs


ORDER = (("ours", "keypoint"), ("ours", "visual"), ("ours", "vanilla"), ("keypoint", "visual"), ("keypoint", "vanilla"))


def order(srs):
    """The paper's Table 1 order (ours above keypoint RL, both above visual and vanilla RL, which did not learn) among
    the rows with multimodal critics, by the one rule (above); srs: table1's third value. Returns ([(A, B, above(A,
    B))] of the pairs run, [the rows not run]); the order holds where every pair is 'above' and none is missing."""
    got = {n: srs[n + MULTIMODAL] for n in ("ours", "keypoint", "visual", "vanilla") if n + MULTIMODAL in srs}
    pairs = [(a, b, above(got[a], got[b])) for a, b in ORDER if a in got and b in got]
    return pairs, [n for n in ("ours", "keypoint", "visual", "vanilla") if n not in got]


def ordering_sentence(srs):
    """order() said: each row's SR at 20 mm, and whether the paper's order holds, or why it is not shown."""
    pairs, missing = order(srs)
    if len(missing) == 4:
        return "No row with multimodal critics is run in this world."
    name = lambda n: "ours" if n == "ours" else TABLE1_ROWS[n].split(" (")[0]        # noqa: E731
    got = {n: srs[n + MULTIMODAL] for n in ("ours", "keypoint", "visual", "vanilla") if n not in missing}
    said = ", ".join(f"{name(n)} {ci(v)}" + (f" ({len(v)} seed{'s' * (len(v) > 1)} so far)" if len(v) < 3 else "")
                     for n, v in got.items())
    short = [(name(a), name(b), v) for a, b, v in pairs if v != "above"]
    reasons = ([verdicts(short) + (" (their intervals overlap)" if any(v == "on the mean only" for *_, v in short)
                                   else "")] if short else [])
    reasons += [f"{listed([name(n) for n in missing])} {'is' if len(missing) == 1 else 'are'} not run yet"] \
        if missing else []
    verdict = "it holds" if not reasons else "not shown, as " + "; ".join(reasons)
    return (f"With multimodal critics (ours), SR at 20 mm ({SEEDS_NOTE}): {said}. The paper's order, ours above "
            f"keypoint RL and both above visual and vanilla RL: {verdict}.")


# ---------------------------------------------------------------- Table 2
def table2(runs, log):
    """Ours, trained as the quickstart trains (stopped when learned), in the training context and at two other places
    of the board, the paper's two unseen contexts (its Table 2 is its real robot's)."""
    md = ["| task | context | seeds | 5 mm | 10 mm | 15 mm | 20 mm | the paper's real robot: SR |",
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
    return ["Each cell: SR / CT (s), the mean over seeds of 20 held-out trials a seed. The paper's column is its "
            "real robot's (its Table 2); ours are simulated: the two stand side by side, not like for like.", "", *md]


# ---------------------------------------------------------------- the ablations, Figs. 9-11
def ablation_table(runs, task, fam, log=print):
    """One of the paper's ablations (COMPARISONS' fam) in numbers, a row a setting, each cell over its seeds: the
    first episode whose E_r reached the run's final range (seed by seed), E_r at the end and the most it reached,
    training success over the last 15 episodes (the paper's Fig. 10 (b)), and the held-out evaluation at the final
    range (20 trials a seed) and at 5-20 mm. [] where fewer than two settings have finished runs."""
    rows = groups_of([r for r in runs if r["eval"]], task, fam)
    if len(rows) < 2:
        return []
    md = ["| setting | seeds | first episode at the final E_r | E_r at the end (mm) | E_r most (mm) | training "
          "success, last 15 | eval SR at the final range | CT there (s) | eval SR at "
          + " / ".join(f"{x:g}" for x in LEVELS) + " mm |", "|---" * 9 + "|"]
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
        md.append(f"| {label} | {len(seeds)} | {' / '.join(first)} | {ci(last, '{:.1f}')} | {np.mean(most):.1f} | "
                  f"{ci(trained)} | {ci(final)} | {f'{np.mean(ct):.2f}' if ct else '-'} | "
                  + " / ".join(f"{v:.2f}" for v in np.nanmean(at, axis=0)) + " |")
    return md


def ablation_block(runs, fam, log):
    """A page's block for one of Figs. 9-11 (the gear's): how many of its planned runs are archived, its table and
    what the paper says of it."""
    exp = ABLATIONS[fam]
    planned = [sweep.config_of([*row, "--seed", str(s)]) for row in sweep.EXPERIMENTS[exp] for s in sweep.SEEDS]
    have = [r for r in runs if r["eval"] and any(is_planned(r, p) for p in planned)]
    md = [f"{len(have)} of {len(planned)} planned runs archived" + ("" if len(have) == len(planned) else
          f"; the rest: `python tools/sweep.py {exp}`, then `python tools/report.py --archive \"runs/{exp}/*\" --to "
          f"results/{exp}`") + f". Each row trained {COMPARISONS[fam][3]} episodes; each cell over its seeds "
          f"({SEEDS_NOTE}; E_r most, CT and the SR at each level: the means).", ""]
    return md + ablation_table(runs, "gear", fam, log) + ["", PAPER_ABLATIONS[fam]]


def curves(runs, out_dir):
    """Each of the paper's comparisons' curves over its seeds (fig-<task>-<comparison>.png), where it has two rows."""
    for task in ("peg", "gear"):
        for fam, (title, keys, _, _) in COMPARISONS.items():
            groups = groups_of(runs, task, fam)
            if len(groups) >= 2:            # one row alone is no comparison
                figures.plot_groups(groups, keys, os.path.join(out_dir, f"fig-{task}-{fam}.png"), f"{task}: {title}")


# ---------------------------------------------------------------- Fig. 12 and Fig. 16
def fig12(runs, task, out_dir, log=print):
    """Fig. 12 for a task: each view's mean cumulative reward per episode (over LEVELS, 20 trials each) in the
    training context, at each of the four locations and their mean, and in the new background; the mean over
    seeds with its 95 % bootstrap interval. The gear's views are its ROI ablation's (200 episodes each), the
    peg's the quickstart's task attention and its full-view twin. Returns (markdown lines, {view: seeds' rewards})."""
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
        return [], cr
    columns = {"train": "training context", "locations": "new locations (mean of 4)",
               FIG12_BACKGROUND: "new background"}
    figures.plot_context_bars({view: {columns[k]: mean_ci(c[k]) for k in columns} for view, c in cr.items()},
                              os.path.join(out_dir, f"fig-{task}-contexts.png"),
                              f"{task}: the training context and unseen ones")
    figures.plot_views(task, tuple(views), contexts_, os.path.join(out_dir, f"fig-{task}-views.png"))
    whose = ("the ROI ablation's policies (Fig. 11's runs, 200 episodes each), as the paper's Fig. 12" if task == "gear"
             else "ours, not the paper's experiment (its Fig. 12 is the gear's ROI ablation): task attention trained "
                  "as the quickstart trains (stopped when learned), the full view as long as its twin of the same seed")
    head = ["training context"] + [f"`{x}`" for x in FIG12_LOCATIONS] + ["locations' mean", "new background"]
    keys = ["train", *FIG12_LOCATIONS, "locations", FIG12_BACKGROUND]
    md = [f"From {whose}. Each cell: the mean cumulative reward per episode over 5/10/15/20 mm (20 trials each on "
          f"held-out seeds), {SEEDS_NOTE}. The new background is `{FIG12_BACKGROUND}`: objects beside the board, "
          "outside the task ROI at every error. The paper's new background differs: its objects show in the view, "
          "and it ties the loss to their size there.", "",
          "| view | " + " | ".join(head) + " |", "|---" * (1 + len(head)) + "|"]
    md += [f"| {view} | " + " | ".join(ci(c[k], "{:.1f}") for k in keys) + " |" for view, c in cr.items()]
    return md + ["", PAPER_FIG12], cr


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


def fig16(runs, world, out_dir):
    """fig-behaviour.png: one episode of the quickstart's peg policy at 10 mm (recorded by this code: only for runs
    of its world)."""
    ours = [r for r in runs if r["cfg"]["task"] == "peg" and method_of(r["cfg"]) == "ours" and r["eval"]]
    ours = [r for r in ours if not fam_of(r)] or ours     # the quickstart's (stopped when learned) first
    if ours and world == sim.WORLD:
        rec, term = record_episode(ours[0], error_mm=10.0)
        figures.plot_behaviour(rec, os.path.join(out_dir, "fig-behaviour.png"),
                               f"one episode, peg, 10 mm error range, success {term}")


# ---------------------------------------------------------------- the quickstart and SB3
def quickstart_sentence():
    """What the quickstart's command gives, from its archived reference runs."""
    runs = sorted((load_run(d) for d in match_runs(QUICKSTART_RUNS)), key=lambda r: r["cfg"]["seed"])
    ev = [r["eval"] for r in runs]
    sr = [next(x["success_rate"] for x in e["rows"] if x["error_mm"] == 20.0) for e in ev]
    episodes, minutes = (", ".join(f"{e[k]:g}" for e in ev) for k in ("train_episodes", "train_minutes"))
    logs = [os.path.join(r["dir"], "train.log") for r in runs]
    walls = [re.search(r"([\d.]+) s wall\s*$", open(p).read()) if os.path.exists(p) else None for p in logs]
    wall = ", ".join(f"{float(w.group(1)) / 60:.1f}" for w in walls) + " min with the evaluation, " \
        if all(walls) else ""                                  # the console's last line, where /usr/bin/time wrote it
    return (f"Seeds {runs[0]['cfg']['seed']}-{runs[-1]['cfg']['seed']} stopped after {episodes} episodes ({minutes} "
            f"min of training, {wall}[results/speed](results/speed), world {ev[0]['world']}) and insert "
            + ", ".join(f"{x:.2f}" for x in sr) + " at 20 mm.")


def sb3_results():
    """bench_sb3.py's archived results of this world (SB3_RUNS), by seed; ArgError where there are none."""
    res = sorted((read_json(p) for p in glob.glob(SB3_RUNS)), key=lambda r: r["seed"])
    if not res or {r.get("world") for r in res} != {sim.WORLD}:
        raise ArgError(f"{SB3_RUNS}: no results of world {sim.WORLD} (python bench/bench_sb3.py --seed S, then copy "
                       "its json there)")
    return res


SB3_WHO = ("SB3's critics read the observation alone, ours are privileged (README difference 13); ours are the "
           "quickstart's command under the stop rule of before issue 49, two validation passes in a row "
           "(`results/speed/halves-s*`, commit 7e0d3b8), which trained longer than today's one pass")


def sb3_sentence():
    """The README's line on SB3's SAC beside ours in the same minutes."""
    res = sb3_results()
    said = lambda who, k, f="g": ", ".join(format(r[who][k], f) for r in res)  # noqa: E731
    return (f"Stable-Baselines3's SAC, given the same env, curriculum and minutes as ours (seeds "
            f"{', '.join(str(r['seed']) for r in res)}; {said('sb3', 'train_minutes', '.1f')} min; world {sim.WORLD}), "
            f"inserts {said('sb3', 'sr20', '.2f')} at 20 mm after {said('sb3', 'episodes')} episodes, against ours' "
            f"{said('ours', 'sr20', '.2f')} after {said('ours', 'episodes')} episodes. {SB3_WHO[0].upper()}"
            f"{SB3_WHO[1:]}.")


def sb3_table():
    """docs/sb3.md's table: a row a seed."""
    crit = lambda m: "not reached" if m is None else f"{m:.1f}"          # noqa: E731
    md = ["| seed | minutes | ours: episodes | ours: to criterion (min) | ours: SR at 20 mm | SB3: episodes | "
          "SB3: final E_r (mm) | SB3: to criterion (min) | SB3: SR at 20 mm |", "|---" * 9 + "|"]
    return md + [f"| {r['seed']} | {r['sb3']['train_minutes']:.1f} | {r['ours']['episodes']} | "
                 f"{crit(r['ours']['to_criterion'])} | {r['ours']['sr20']:.2f} | {r['sb3']['episodes']} | "
                 f"{r['sb3']['final_e_r_mm']:g} | {crit(r['sb3']['to_criterion'])} | {r['sb3']['sr20']:.2f} |"
                 for r in sb3_results()] + ["", f"{SB3_WHO[0].upper()}{SB3_WHO[1:]}."]


# ---------------------------------------------------------------- the README's findings
def findings(runs, srs, ts_row, gear_fig12):
    """The README's lines of findings: one a result beside the paper's, its numbers made here, with its page."""
    lines = []
    if "ours" in srs:
        lines.append(f"- **Table 1** (peg, 20 mm): ours {ci(srs['ours'])}, the paper's 1.00"
                     + (f"; two-step {ts_row['success_rate']:.2f}, the paper's 0.533" if ts_row else "")
                     + (f"; with multimodal critics (ours) {ci(srs['ours' + MULTIMODAL])}"
                        if "ours" + MULTIMODAL in srs else "") + ". [table1](docs/table1.md)")
    last = lambda fam: {k: [float(r["m"]["e_r_mm"][-1]) for r in v]                     # noqa: E731
                        for k, v in groups_of([r for r in runs if r["eval"]], "gear", fam).items()}
    obs = last("obs")
    if {"P-T", "Time-series P-T", "Time-series P-T-V"} <= set(obs):
        lines.append(f"- **Fig. 9** (gear, E_r after 200 episodes, mm): with vision {ci(obs['Time-series P-T-V'], '{:.1f}')}"
                     f", P-T {ci(obs['P-T'], '{:.1f}')}, time-series P-T {ci(obs['Time-series P-T'], '{:.1f}')}; the "
                     "paper's about 10, 5 and between; "
                     + verdicts([("vision", "P-T", above(obs["Time-series P-T-V"], obs["P-T"])),
                                 ("time-series P-T", "P-T", above(obs["Time-series P-T"], obs["P-T"]))])
                     + ". [fig9](docs/fig9-observations.md)")
    trained = {k: [float(np.mean(r["m"]["success"][-15:])) for r in v]
               for k, v in groups_of([r for r in runs if r["eval"]], "gear", "curriculum").items()}
    at30 = {k.split(",")[0].replace("curriculum ", ""): v for k, v in trained.items() if k.endswith("30 mm")}
    if "no curriculum" in at30 and len(at30) > 1:
        rest = [k for k in sorted(at30) if k != "no curriculum"]
        lines.append("- **Fig. 10** (gear at 30 mm, training success over the last 15 of 300 episodes): "
                     + ", ".join(f"{k} {ci(at30[k])}" for k in rest + ["no curriculum"]) + "; "
                     + verdicts([(ks, "none", v) for v in ("above", "on the mean only", "not above")
                                 for ks in [[k for k in rest if above(at30[k], at30["no curriculum"]) == v]] if ks])
                     + "; the paper's every curriculum is above none. [fig10](docs/fig10-curricula.md)")
    if gear_fig12:
        (v3, c3), (vf, cf) = list(gear_fig12.items())[:2]
        lines.append(f"- **Fig. 12** (gear, reward at four new locations): {v3.split(' (')[0]} "
                     f"{ci(c3['locations'], '{:.1f}')}, the full view {ci(cf['locations'], '{:.1f}')}; the paper's "
                     "46.46 and -14.65. [fig12](docs/fig12-contexts.md)")
    return lines


# ---------------------------------------------------------------- the blocks
def make(patterns=REPORT_RUNS, out_dir="docs", log=print):
    """Every block this module makes, from the run directories that `patterns` match (all of one world), with
    the figures written to out_dir: {block name: markdown}."""
    runs = [load_run(d) for d in match_runs(patterns)]
    world = world_of(runs, patterns)
    os.makedirs(out_dir, exist_ok=True)
    ts_row = two_step_row(out_dir, world, log)
    md1, readme1, srs = table1(runs, ts_row)
    said = f"Made by `python tools/report.py` from {len(runs)} runs of world {world}"
    made = {"table1": "\n".join([said + ".", "", *md1, "", ordering_sentence(srs)]),
            "readme-table1": "\n".join(readme1), "table2": "\n".join([said + ".", "", *table2(runs, log)])}
    if glob.glob(QUICKSTART_RUNS):          # the quickstart's reference runs, and SB3's, where they are archived
        made["quickstart"] = quickstart_sentence()
    if glob.glob(SB3_RUNS):
        made.update({"sb3": "\n".join(sb3_table()), "readme-sb3": sb3_sentence()})
    for fam, page in (("obs", "fig9"), ("curriculum", "fig10"), ("roi", "fig11")):
        made[page] = "\n".join(ablation_block(runs, fam, log))
    gear_fig12 = {}
    for task in ("peg", "gear"):
        md, cr = fig12(runs, task, out_dir, log)
        made[f"fig12-{task}"] = "\n".join(md) if md else f"Not run in world {world}."
        gear_fig12 = cr if task == "gear" else gear_fig12
    curves(runs, out_dir)
    fig16(runs, world, out_dir)
    made["readme-findings"] = "\n".join(findings(runs, srs, ts_row, gear_fig12))
    return made
