"""report.py: the paper's experiments, re-made from the archived runs in results/, written into the pages that show
them: the README and docs/ are prose a person writes, with named blocks the report makes (pages.py), so that no
number of results is typed. What each part makes: results.py (Tables 1-2, Figs. 9-12 and 16, SB3 beside ours),
scenes.py (every named context, the families of scenes, the robust option), robust.py (--robust: the episodes and
time it takes), compare.py (a table of learning settings); runs.py reads the runs and keeps the archive.

    python tools/report.py --archive "runs/table1/*" --to results/table1   # finished runs -> results/table1/<run>/
    python tools/report.py                       # results/{table1,contexts,gear-*} -> README.md, docs/*.md, fig-*.png
    python tools/report.py --contexts --jobs 2   # every context and family -> docs/contexts.md, families.md, README
    python tools/report.py --check               # every block of the pages is what the report makes now (CI)

It evaluates what it needs and has not got yet (the two-step baseline, the unseen contexts) and caches those rows
beside the runs, so that a second report reads them back.
"""
import glob
import os
import shutil
import signal
import sys
import tempfile

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\nreport: interrupted\n"), os._exit(130)))

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the core modules, one folder up
import cli  # noqa: E402
import compare  # noqa: E402
import pages  # noqa: E402
import results  # noqa: E402
import robust  # noqa: E402
import scenes  # noqa: E402
from cli import ArgError  # noqa: E402
from runs import RESULTS_DIR, archive_runs  # noqa: E402


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CODE_MAP = {   # the README's code map: each file of the core and what of the paper it holds (code_map adds its size)
    "tacrl.py": "the run's config (every flag, by group), Algorithm 1 (`train`, one screen), `main`",
    "command.py": "its command line: flags checked against each other and the files they name; `--eval`",
    "cli.py": "what every command shares: flags declared once, `--help` by group, one-line mistakes (exit 2)",
    "sim.py": "the paper's task: ROI (Eq. 11), errors (Eq. 13-15), reward and success (Eq. 17-18); the Gymnasium env",
    "scene.py": "the PyBullet workcell: UR5, boards, wrist sensor, camera, fence, tape, spare parts (Sec. 5.1.1)",
    "shapes.py": "the boxes its exact holes, chamfers, gear teeth and the board's bumps are built from; numpy only",
    "contexts.py": "the scenes it is tested in: named contexts and seeded families (Sec. 5.1.4, Fig. 12)",
    "control.py": "admittance law, stiffness, trajectory, hybrid policy (Sec. 4.1, Eq. 3-9); numpy only",
    "curriculum.py": "adaptive error curriculum and the ablation's schedules (Sec. 4.3.1, Eq. 16); numpy only",
    "policy.py": "TA-MRP networks, critics, replay buffer, SAC (Sec. 4.2.2, 4.3.2); torch, numpy",
    "evaluate.py": "Tables 1-2: SR, CT, CF, CR on held-out seeds; a policy file; a video a browser plays",
    "rundir.py": "what a run directory holds: config, checkpoint, replay files, metrics, curves",
    "baselines.py": "the two-step baseline: visual servo, spiral search, insertion (Sec. 5.1.2)",
    "tacrl_flat.py": "the guard that names a module of ours another installed package shadows",
    "tools/": "the report (`report.py`: `results.py`, `scenes.py`, `robust.py`, `compare.py`, `runs.py`, `pages.py`), "
              "`figures.py`, `sweep.py` (experiments, here or on Ray), studies (`critics.py`, `objects.py`, `touch.py`)",
}


def code_map():
    """The README's code map: a row a file (a folder: its .py files together) with its lines."""
    def lines(name):
        path = os.path.join(ROOT, name)
        files = sorted(glob.glob(os.path.join(path, "*.py"))) if name.endswith("/") else [path]
        return sum(sum(1 for _ in open(f)) for f in files)
    return "\n".join(["| file | lines | what (paper) |", "|---|---|---|"]
                     + [f"| `{name}` | {lines(name)} | {what} |" for name, what in CODE_MAP.items()])


def page_paths(out_dir, readme):
    """The pages whose blocks the report fills: the README and every page of out_dir."""
    return [readme] + sorted(glob.glob(os.path.join(out_dir, "*.md")))


def write(made, out_dir, readme, log=print):
    """Fill the pages' blocks with `made`; a block no page holds is said, in a line (its page lost its markers)."""
    filled = pages.fill_all(page_paths(out_dir, readme), made, log)
    for name in sorted(set(made) - filled):
        log(f"report: no page holds the block {name!r} (<!-- report: {name} --> ... <!-- end -->); not written")


def check(out_dir, readme, log=print):
    """Every block of the pages against what the report makes of results/ now, its figures drawn in a temporary
    folder: Failed naming each that differs (typed by hand, or results/ changed since)."""
    quiet = lambda *_: None                     # noqa: E731
    with tempfile.TemporaryDirectory() as tmp:
        cached = os.path.join(out_dir, "two-step-peg-20mm.json")
        if os.path.exists(cached):              # the two-step row, as the report keeps it with its world
            shutil.copy(cached, tmp)
        made = {**results.make(out_dir=tmp, log=quiet), **scenes.make(out_dir=tmp, log=quiet), "code-map": code_map(),
                **scenes.scene_table(log=quiet), **robust.make()}
    differ = [f"{p}: {name}" for p in page_paths(out_dir, readme) for name in pages.stale(p, made)]
    if differ:
        raise cli.Failed(f"{'; '.join(differ)}: not what the report makes of {RESULTS_DIR}/ now (python "
                         "tools/report.py, and --contexts, make them anew)")
    log(f"{readme} and {out_dir}/*.md: every block is the report's")


def main(argv=None):
    ap = cli.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="?", help="comma-separated glob patterns of run directories (default: "
                    f"{results.REPORT_RUNS}; with --contexts or --families, {scenes.CONTEXT_RUNS})")
    ap.add_argument("--archive", action="store_true", help="copy the finished runs' small files to --to instead")
    ap.add_argument("--to", default=RESULTS_DIR, help=f"where --archive copies to (default: {RESULTS_DIR})")
    ap.add_argument("--out", default=os.path.join(ROOT, "docs"), help="the folder of the pages and their figures "
                    "(default: the project's docs/)")
    ap.add_argument("--readme", default=os.path.join(ROOT, "README.md"), help="the README whose blocks are filled too "
                    "(default: the project's)")
    ap.add_argument("--contexts", action="store_true", help="evaluate ours and its full view in every context and "
                    "family instead (Fig. 12 beyond the paper: docs/contexts.md, families.md)")
    ap.add_argument("--families", action="store_true", help="the families alone instead (docs/families.md)")
    ap.add_argument("--scenes", action="store_true", help="every held-out scene of every family instead, "
                    f"{scenes.SCENES} a family, {scenes.SCENE_EPISODES} episodes each (default runs: "
                    f"{scenes.SCENE_RUNS}; docs/families.md's block scenes)")
    ap.add_argument("--compare", default="", metavar="NAME", help="a table and curves of the runs by learning setting "
                    "instead, to --out/NAME.md and NAME.png")
    ap.add_argument("--check", action="store_true", help="check that the pages' blocks are what the report makes of "
                    "the archived runs now, instead (exit 1 where not)")
    ap.add_argument("--jobs", type=int, default=1, help="processes for --contexts' evaluations (one torch thread each)")
    a = ap.parse_args(argv)
    if a.jobs < 1:
        raise ArgError(f"--jobs must be at least 1, not {a.jobs}")
    if a.runs is None and (a.archive or a.compare):
        raise ArgError(f"--{'archive' if a.archive else 'compare'} takes the run directories, e.g. \"runs/*\"")
    if not a.archive and not a.compare and not os.path.isfile(a.readme):
        raise ArgError(f"--readme {a.readme!r}: no such file")
    if a.archive:
        archive_runs(a.runs, a.to)
    elif a.compare:
        if not a.compare.replace("-", "").replace("_", "").isalnum():
            raise ArgError(f"--compare takes a file name of letters, digits, - and _, not {a.compare!r}")
        compare.write_compare(a.runs, a.out, a.compare)
    elif a.check:
        check(a.out, a.readme)
    elif a.scenes:
        cli.check_dir_writable(a.out, "--out")
        write(scenes.scene_table(a.runs or scenes.SCENE_RUNS, jobs=a.jobs), a.out, a.readme)
    elif a.contexts or a.families:
        cli.check_dir_writable(a.out, "--out")
        write(scenes.make(a.runs or scenes.CONTEXT_RUNS, a.out, jobs=a.jobs, named=a.contexts), a.out, a.readme)
    else:
        cli.check_dir_writable(a.out, "--out")
        write({**results.make(a.runs or results.REPORT_RUNS, a.out), "code-map": code_map(), **robust.make()}, a.out,
              a.readme)


if __name__ == "__main__":
    sys.exit(cli.command("report", main))
