"""seeds.py: several independent training runs of tacrl.py, one a seed, in parallel processes. The
paper's learning curves are means over three repeated experiments (Sec. 5.1.5), and a learning claim
here needs its seeds too:

    python tools/seeds.py 0,1,2 --task peg                 # runs/peg-ts-ptv-adaptive-s0, -s1, -s2
    python tools/seeds.py 0,1 --task peg --curriculum none --error-mm 10

The flags after the seeds are tacrl.py's. At most one process a core runs at a time, each with torch
on cores / processes threads: two torch processes with the default threads on the same two cores
slowed one update phase from 6 s to 231 s. Each run is an ordinary run directory with its own
train.log, resumable on its own with `python tacrl.py --resume DIR`.
"""
import os
import re
import signal
import subprocess
import sys
import time

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\nseeds: interrupted\n"), os._exit(130)))

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the core modules, one folder up
import rundir  # noqa: E402
import tacrl  # noqa: E402
from tacrl import ArgError  # noqa: E402


def strip_flag(argv, flag):
    """argv without `flag VALUE` / `flag=VALUE`."""
    out, skip = [], False
    for x in argv:
        if skip:
            skip = False
        elif x == flag:
            skip = True
        elif not x.startswith(flag + "="):
            out.append(x)
    return out


def seed_commands(seeds, argv, cores=None):
    """How many processes at once, and (seed, run dir, command line, environment) for each seed; argv: tacrl.py's
    flags. Each seed's own command line is checked as tacrl.py will check it (its run dir must be new
    or empty) before any run starts."""
    given = tacrl.parse(tacrl.Config, argv, "")        # the flags as typed, checked below with each seed
    if "eval" in given or "resume" in given:
        raise ArgError("seeds.py trains; --eval and --resume are for one run (tacrl.py)")
    base = argv
    for flag in ("--seed", "--run-dir", "--threads"):
        base = strip_flag(base, flag)
    cores = cores or os.cpu_count() or 1
    parallel = min(len(seeds), cores)
    stem = re.sub(r"-s\d+$", "", given.get("run_dir") or tacrl.default_run_dir(tacrl.Config(**given)))
    threads = given.get("threads") or max(1, cores // parallel)     # threads x processes <= cores
    tacrl.warn_oversubscribed("seeds", threads, parallel, cores)
    env = {**os.environ, **{k: str(threads) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}}
    jobs = []                                        # (numpy's BLAS and OpenMP get torch's thread count too)
    for s in seeds:
        cmd = base + ["--seed", str(s), "--run-dir", f"{stem}-s{s}", "--threads", str(threads)]
        cfg = tacrl.parse_args(cmd)              # a bad seed, or a run dir that holds a run: before anything starts
        jobs.append((s, cfg.run_dir, [sys.executable, os.path.abspath(tacrl.__file__), *cmd], env))
    return parallel, jobs


def train_seeds(seeds, argv):
    """Start the runs, at most `parallel` at a time; a progress line a minute. Raises tacrl.Failed naming
    the seeds whose runs failed."""
    parallel, jobs = seed_commands(seeds, argv)
    todo, running, failed, t0 = list(jobs), {}, [], time.time()
    shown = t0                                       # the first progress line after a minute
    while todo or running:
        while todo and len(running) < parallel:
            s, run_dir, cmd, env = todo.pop(0)
            os.makedirs(run_dir, exist_ok=True)
            with open(os.path.join(run_dir, rundir.LOG), "a") as log:
                running[s] = (subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env), run_dir)
            print(f"seed {s}: started, {run_dir}/{rundir.LOG}", flush=True)
        time.sleep(0.2)                          # a run that ends is seen at once, its log read once a minute
        if time.time() - shown > 60:
            shown = time.time()
            status = "  ".join(last_episode(s, run_dir) for s, (_, run_dir) in running.items())
            print(f"[{rundir.fmt_time(shown - t0)}] episodes: {status}", flush=True)
        for s, (proc, run_dir) in list(running.items()):
            if proc.poll() is not None:
                del running[s]
                failed += [(s, proc.returncode)] if proc.returncode else []
                print(f"seed {s}: finished with exit code {proc.returncode} ({rundir.fmt_time(time.time() - t0)})",
                      flush=True)
    if failed:
        raise tacrl.Failed(f"the runs of seed{'s' * (len(failed) > 1)} {', '.join(str(s) for s, _ in failed)} failed "
                         f"(exit code{'s' * (len(failed) > 1)} {', '.join(str(c) for _, c in failed)}): see their "
                         f"{rundir.LOG}")


def last_episode(s, run_dir):
    """'s<seed> <episode>/<of>' from the run's log, '-' before its first episode."""
    with open(os.path.join(run_dir, rundir.LOG)) as f:
        last = [ln for ln in f.read().splitlines() if ln.startswith("ep ")]
    return f"s{s} {last[-1].split()[1] if last else '-'}"


def parse_seeds(text):
    try:
        seeds = [int(x) for x in text.split(",")]
    except ValueError:
        seeds = []
    if not seeds or len(set(seeds)) != len(seeds):
        raise ArgError(f"the first argument must be distinct comma-separated seeds, e.g. 0,1,2, not {text!r}")
    return seeds


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in ("-h", "--help"):         # this page, then tacrl.py's flags
        print(__doc__.strip() + "\n")
        tacrl.parse_args(["--help"])
    if not argv or argv[0].startswith("-"):
        raise ArgError("usage: python tools/seeds.py SEEDS [tacrl.py flags], e.g. python tools/seeds.py 0,1,2 --task peg")
    train_seeds(parse_seeds(argv[0]), argv[1:])


if __name__ == "__main__":
    sys.exit(tacrl.command("seeds", main))
