"""robust.py: what the robust option costs, and when it holds (issue 83; docs/robust.md). Three blocks:
`robust-before`, when the option's archived runs (made before --robust, their families as then drawn) first held
every family, from the evaluations kept beside them; and `robust-runs`, the --robust runs (`python tools/sweep.py
robust-flag`) beside the quickstart's command on the same machine at the same threads (`python tools/sweep.py
quickstart`): their episodes, their time against the bench figure, and each validation of the stop rule; and
`robust-first-look`, a run that 10 scenes a family stopped alone, beside its held-out scenes (why a pass is confirmed).
"""
import glob
import os
import re

import numpy as np

import tacrl
from cli import ArgError
from runs import RESULTS_DIR, load_run, match_runs, read_json

HOLD = 0.9                  # the bar: SR at 20 mm in training's scene and every held-out family
MM = 20.0
# the option's runs of issue 53, one lineage a (task, seed): first trained to 300 episodes or a stop (tilt/), then
# copies resumed to 400-500 (ext*/) and 600 (ep600/); their policies left the archive, their evaluations stay
BEFORE = ",".join(f"{RESULTS_DIR}/{e}/*" for e in ("tilt", "ext", "ext400", "ext500", "ep600"))
OPTION_FAMILIES = ("place", "light", "colour", "parts", "objects", "touch", "mixed")   # as the option's runs drew them
FLAG_RUNS, YARDSTICK = f"{RESULTS_DIR}/robust-flag/*", f"{RESULTS_DIR}/quickstart/*"
FIRST_LOOK = f"{RESULTS_DIR}/robust-first-look/*"   # --robust stopped by 10 scenes a family alone (the rule before 30)
BENCH = re.compile(r"ts-ptv critics privileged: median\s+([\d.]+) updates/s")


def sr_at(rows, mm=MM):
    return next(r["success_rate"] for r in rows if r["error_mm"] == mm)


def archived_families(run):
    """{family: SR at 20 mm} of a run as its archive holds them (eval-ctx-FAMILY-test.json: 20 held-out trials,
    each family as drawn when it was evaluated), and 'train' from eval.json."""
    out = {"train": sr_at(run["eval"]["rows"])}
    for f in OPTION_FAMILIES:
        path = os.path.join(run["dir"], f"eval-ctx-{f}-test.json")
        if os.path.exists(path):
            out[f] = sr_at(read_json(path)["rows"])
    return out


def before_rows(patterns=BEFORE):
    """[(task, seed, episodes, {family: SR})] of the option's runs, a lineage's in the order it trained."""
    out = []
    for d in match_runs(patterns):
        run = load_run(d)
        if "mixed" in run["cfg"]["randomize"]:              # (tilt/ also holds the option without mixed)
            out.append((run["cfg"]["task"], run["cfg"]["seed"], run["eval"]["train_episodes"], archived_families(run)))
    return sorted(out, key=lambda r: r[:3])


def before_table(rows):
    """The block robust-before: a row a run, with the lowest SR over training's scene and the families and the
    families below HOLD; then, a lineage a line, the episodes at which it first held them all."""
    md = [f"Made by `python tools/report.py` from the archived runs of the robust option (`{BEFORE}`; world 22; "
          f"each family as drawn then: mixed without reach and calib). SR at {MM:g} mm, 20 held-out trials a family. "
          "Each (task, seed) is one lineage: a run trained to 300 episodes or its stop, then copies of it resumed to "
          "more (`--resume RUN --train-episodes N --stop-held 0`).",
          "", "| task | seed | episodes | train | lowest | below 0.9 |", "|---|---|---|---|---|---|"]
    first = {}
    for task, seed, episodes, sr in rows:
        low = min(sr.values())
        below = ", ".join(f"{f} {v:.2f}" for f, v in sr.items() if v < HOLD) or "-"
        md.append(f"| {task} | {seed} | {episodes} | {sr['train']:.2f} | {low:.2f} | {below} |")
        first.setdefault((task, seed), []).append((episodes, low >= HOLD))
    said = []
    for (task, seed), evs in sorted(first.items()):
        at = next((i for i, (_, ok) in enumerate(evs) if ok), None)
        said.append(f"{task} seed {seed}: " + (f"not by {evs[-1][0]}" if at is None else f"at {evs[at][0]}"
                                                + (f" (not at {evs[at - 1][0]})" if at else "")))
    return "\n".join(md + ["", "First held every family: " + "; ".join(said) + "."])


def bench_of(path):
    """bench/bench_sac.py's privileged ts-ptv figure (updates/s) in a saved console, or None."""
    if not os.path.exists(path):
        return None
    m = BENCH.search(open(path).read())
    return float(m.group(1)) if m else None


def families_of(run):
    """The families a run randomized (tacrl.Config.families of its config.json)."""
    return tuple(f for f in run["cfg"]["randomize"].split(",") if f)


def missed(v, families):
    """What a validation that did not hold lacked: training's scene, or the families below the stop rule's bar."""
    if v["train"] < tacrl.VAL_WINS:
        return f"train {v['train']}/{tacrl.VAL_EPISODES}"
    if "confirm" in v:                  # a first look that passed, not confirmed
        return ", ".join(f"{f} {v['confirm'][f]}/{tacrl.FAMILY_CONFIRM}" for f in families
                         if v["confirm"][f] < tacrl.FAMILY_CONFIRM_WINS)
    return ", ".join(f"{f} {v[f]}/{tacrl.FAMILY_EPISODES}" for f in families if v[f] < tacrl.FAMILY_WINS) or \
        f"stopped here on {tacrl.FAMILY_EPISODES} scenes a family, unconfirmed (before the rule's confirmation)"


def flag_runs(robust=FLAG_RUNS, yardstick=YARDSTICK):
    """(the finished --robust runs, the quickstart's, [(when, bench figure)] saved beside them)."""
    runs = [r for r in (load_run(d) for d in match_runs(robust)) if r["eval"]]
    try:
        yard = [r for r in (load_run(d) for d in match_runs(yardstick)) if r["eval"]]
    except ArgError:                    # the yardstick not archived yet: its cells are dashes
        yard = []
    folder = os.path.dirname(robust)                       # (the pattern's folder: results/robust-flag)
    benches = [(os.path.basename(p)[len("bench-"):-len(".txt")], bench_of(p))      # bench-before.txt, bench-after.txt
               for p in sorted(glob.glob(os.path.join(folder, "bench-*.txt")), reverse=True)]
    return sorted(runs, key=lambda r: (r["cfg"]["task"], r["cfg"]["seed"])), yard, benches


def readme_time(robust=FLAG_RUNS, yardstick=YARDSTICK):
    """The README's block readme-robust: each --robust run's episodes and minutes, the bench figure, and the
    quickstart's median minutes run the same way."""
    runs, yard, benches = flag_runs(robust, yardstick)
    said = []
    for task in sorted({r["cfg"]["task"] for r in runs}):
        mine = [r for r in runs if r["cfg"]["task"] == task]
        quick = [r["eval"]["train_minutes"] for r in yard if r["cfg"]["task"] == task]
        seeds = ", ".join(str(r["cfg"]["seed"]) for r in mine)
        episodes = ", ".join(str(r["eval"]["train_episodes"]) for r in mine)
        minutes = ", ".join(f"{r['eval']['train_minutes']:.0f}" for r in mine)
        said.append(f"the {task}'s seed{'s' * (len(mine) > 1)} {seeds} trained {episodes} episodes in {minutes} min"
                    + (f" (the quickstart's command: a median of {np.median(quick):.0f} min)" if quick else ""))
    bench = ", ".join(f"{b:g} updates/s {when} them" for when, b in benches if b) or "-"
    return (f"Its reference runs ([results/robust-flag](results/robust-flag), world 22, each `--threads 1` beside "
            f"another run on 2 cores, at times a third process too; `bench/bench_sac.py`: {bench}): "
            + "; ".join(said) + ".")


def flag_table(robust=FLAG_RUNS, yardstick=YARDSTICK):
    """The block robust-runs: each --robust run (episodes, minutes, the validations that did not hold, where it
    stopped) beside the quickstart's runs of its task; the medians' ratio; the bench figure saved beside them."""
    runs, yard, benches = flag_runs(robust, yardstick)
    md = [f"Made by `python tools/report.py` from `{robust}` (`python tools/sweep.py robust-flag`) and `{yardstick}` "
          f"(`python tools/sweep.py quickstart`): each run `--threads 1` beside another run on the 2-core machine, at "
          f"times a third process too (the report's evaluations, tests), so the minutes are upper bounds "
          f"(`bench/bench_sac.py`, privileged ts-ptv, updates/s: "
          f"{', '.join(f'{when} {b:g}' for when, b in benches if b) or '-'}). Minutes: training with its "
          "validations, not the evaluation after it (eval.json's train_minutes).", "",
          "| task | seed | episodes | stopped as learned | first held (episode) | validations that did not hold "
          "| minutes |",
          "|---|---|---|---|---|---|---|"]
    for r in runs:
        fams = families_of(r)
        val = r["eval"].get("validation", [])
        holds = [tacrl.StopRule.holds(v, fams) for v in val]
        first = next((v["episode"] for v, ok in zip(val, holds) if ok), None)
        lacked = "; ".join(f"{v['episode']}: {missed(v, fams)}" for v, ok in zip(val, holds) if not ok) or "-"
        episodes = r["eval"]["train_episodes"]
        stopped = "yes" if episodes < r["cfg"]["train_episodes"] else "no"
        md.append(f"| {r['cfg']['task']} | {r['cfg']['seed']} | {episodes} | {stopped} | "
                  f"{first or '-'} | {lacked} | {r['eval']['train_minutes']:.1f} |")
    md += ["", "| task | --robust, median minutes | the quickstart's, median minutes | ratio |", "|---|---|---|---|"]
    for task in sorted({r["cfg"]["task"] for r in runs}):
        a = [r["eval"]["train_minutes"] for r in runs if r["cfg"]["task"] == task]
        b = [r["eval"]["train_minutes"] for r in yard if r["cfg"]["task"] == task]
        ratio = f"{np.median(a) / np.median(b):.1f}" if b else "-"
        md.append(f"| {task} ({len(a)} and {len(b)} seeds) | {np.median(a):.1f} | "
                  f"{f'{np.median(b):.1f}' if b else '-'} | {ratio} |")
    return "\n".join(md)


def first_look_table(patterns=FIRST_LOOK):
    """The block robust-first-look: runs that 10 scenes a family stopped alone, their last validation beside the
    held-out families (20 trials each, eval-ctx-FAMILY-test.json) and, where evaluated, each family's 100 held-out
    scenes (eval-scenes-FAMILY.json: the mean SR and the share of scenes below 0.5)."""
    md = [f"Made by `python tools/report.py` from `{patterns}` (world 22): the stop's validation (training-side scenes "
          f"of each family, successes of {tacrl.FAMILY_EPISODES}), the held-out family at 20 mm (20 trials) and, "
          "where evaluated, its "
          "first 100 held-out scenes x 3 episodes (mean SR / share of scenes below 0.5).", "",
          "| task | seed | stopped at | family | validation | held-out, 20 trials | 100 scenes |",
          "|---|---|---|---|---|---|---|"]
    for d in match_runs(patterns):
        run = load_run(d)
        last = run["eval"]["validation"][-1]
        for f in families_of(run):
            ctx = os.path.join(d, f"eval-ctx-{f}-test.json")
            held = f"{sr_at(read_json(ctx)['rows']):.2f}" if os.path.exists(ctx) else "-"
            path = os.path.join(d, f"eval-scenes-{f}.json")
            rates = np.array(read_json(path)["rates"]) if os.path.exists(path) else None
            many = "-" if rates is None else f"{rates.mean():.2f} / {(rates < 0.5).mean():.2f}"
            md.append(f"| {run['cfg']['task']} | {run['cfg']['seed']} | {last['episode']} | {f} | "
                      f"{last[f]}/{tacrl.FAMILY_EPISODES} | "
                      f"{held} | {many} |")
    return "\n".join(md)


def make():
    """{block: markdown} of docs/robust.md, each where its runs are archived (else the page's block stays as it is)."""
    made = {}
    for name, block in (("robust-before", lambda: before_table(before_rows())), ("robust-runs", flag_table),
                        ("robust-first-look", first_look_table), ("readme-robust", readme_time)):
        try:
            made[name] = block()
        except ArgError:                # no such run archived (yet, or here)
            pass
    return made
