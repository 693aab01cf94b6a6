"""compare.py: a comparison of learning settings (docs/critics.md: the critics study's runs): a row a run,
finished or not, with what its critics read, its curriculum, its evaluation and tools/critics.py's diagnostics, and
the curves grouped by setting: `python tools/report.py "runs/peg-*" --compare NAME` -> the block NAME of a page of
docs/ (docs/critics.md holds `critics-runs`), or docs/NAME.md where none holds it; and NAME.png.
"""
import glob
import os

import numpy as np

import cli
import command
import figures
import pages
from runs import LEVELS, load_run, match_runs, method_of, read_json, world_of


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
    """A comparison of learning settings (docs/critics.md's runs): every run, finished or not, one row each
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
          f"defaults; those of the critics study (issues 31 and 50) are in commit {command.STUDY_COMMIT}.", "",
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
    made = {name: "\n".join(md)}
    if not pages.fill_all(sorted(glob.glob(os.path.join(out_dir, "*.md"))), made, log):     # a page's block NAME,
        with open(os.path.join(out_dir, f"{name}.md"), "w") as f:                          # else a page of its own
            f.write("\n".join(md) + "\n")
        log(f"wrote {out_dir}/{name}.md")
    log(f"wrote {out_dir}/{name}.png")
    return 0
