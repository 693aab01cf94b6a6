"""sweep.py: the report's experiments as a plan of independent, resumable runs of tacrl.py, each in a run
directory of its own, executed as local processes (the default: at most one a core, threads an update x
processes <= cores) or as Ray tasks (the `ray` extra: a local Ray instance, or a cluster's address).
A run that has finished (eval.json) is skipped, one that was stopped is resumed, so the same command
picks a sweep up where it stopped; report.py reads whatever has finished. A run whose process or machine is lost
(killed by a signal) is resumed from its checkpoint, up to --retries times (on Ray, by Ray's task retries); one
that stops on a full or read-only disk (exit code 74) or a mistake (2) is reported by name and not retried.

    python tools/sweep.py --list                                  # the experiments and their runs
    python tools/sweep.py table1 --seeds 0,1,2                     # Table 1's learned rows -> runs/table1/...
    python tools/sweep.py gear-obs,gear-roi --dry-run              # the commands, nothing run
    python tools/sweep.py --seeds 0,1,2 -- --task peg --obs v      # any tacrl.py flags, several seeds
    python tools/sweep.py table1 --ray auto --root /shared/runs    # as Ray tasks on a running cluster

With --ray, every node must see the project and --root at the same paths (a shared file system): a
task runs `python <project>/tacrl.py ... --run-dir <root>/...` there and writes its run dir, which the
report on any node then reads. Each run's output goes to its run dir's train.log.
"""
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\nsweep: interrupted\n"), os._exit(130)))

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the core modules, one folder up
import cli  # noqa: E402
import command  # noqa: E402
import rundir  # noqa: E402
import tacrl  # noqa: E402
from cli import ArgError  # noqa: E402

# The paper's experiments (Sec. 5.1.2-5.1.5), each a list of tacrl.py flag lists, one a learned row; every
# row of an experiment trains for the same number of episodes (--stop-held 0: no stopping when learned),
# as the paper compares them. The seeds are added to each.
BUDGET = lambda n: ["--train-episodes", str(n), "--stop-held", "0"]   # noqa: E731
# the robust option (issue 53, docs/families.md): trained among every family, each image standardised, room for a tilt
OPTION = {"--randomize": "light,colour,parts,objects,touch,mixed", "--image-norm": "image", "--tilt-deg": "1"}
FLAGS = lambda d: [x for flag_value in d.items() for x in flag_value]     # noqa: E731  {flag: value} -> argv


def leave_one_out():
    """{the part left out: OPTION's flags without it}, each family of --randomize, then each other flag."""
    families = OPTION["--randomize"].split(",")
    less = {out: {**OPTION, "--randomize": ",".join(f for f in families if f != out)} for out in families}
    less.update({out: {k: v for k, v in OPTION.items() if k != out} for out in OPTION if out != "--randomize"})
    return {out: FLAGS(d) for out, d in less.items()}


EXPERIMENTS = {
    # peg, 200 ep.
    "table1": [[*row, *BUDGET(200)] for row in ([], ["--vanilla"], ["--obs", "v"], ["--obs", "ts-ptk"])],
    "gear-obs": [["--task", "gear", "--curriculum", "ex10", "--obs", o, *BUDGET(200)]
                 for o in ("pt", "ts-pt", "ts-ptv")],
    "gear-curriculum": [["--task", "gear", "--curriculum", c, "--error-mm", mm, *BUDGET(300)]       # Fig. 10
                        for c, mms in (("adaptive", ("10", "20", "30")), ("none", ("10", "20", "30")),
                                       ("g2-c30", ("30",)), ("g2-c10", ("30",)), ("g2-c2", ("30",))) for mm in mms],
    "gear-roi": [["--task", "gear", "--roi", r, *BUDGET(200)] for r in ("task", "full", "300", "200", "100x160")],
    "contexts": [["--task", t, "--roi", r] for t in ("peg", "gear") for r in ("task", "full")],  # stop when learned
    # beyond the paper: the families of scenes (report.py --contexts), the paper's method against photometric
    # jitter, training scenes drawn from the families (places stay held out), and those with each image standardised
    "robust": [["--task", t, "--roi", r, *o] for t in ("peg", "gear") for r in ("task", "full")
               for o in ([], ["--augment", "0.4"], ["--randomize", "light,colour,parts"],
                         ["--randomize", "light,colour,parts", "--image-norm", "image"])],
    # issue 53's robust option at 600 episodes, and it with each of its parts left out: its leave-one-out (the
    # peg's rows first, then the gear's)
    "option": [["--task", t, *FLAGS(OPTION), *BUDGET(600)] for t in ("peg", "gear")],
    "option-loo": [["--task", t, *flags, *BUDGET(600)] for t in ("peg", "gear") for flags in leave_one_out().values()],
    # issue 83: --robust, stopped when it holds in every family, and the quickstart's command beside it on the same
    # machine at the same threads (its time's yardstick)
    "robust-flag": [["--task", t, "--robust"] for t in ("peg", "gear")],
    "quickstart": [["--task", t] for t in ("peg", "gear")],
}
SEEDS = (0, 1, 2)     # the seeds of a row of the report's tables: 3, as the task's bar asks where a table shows one
PROJECT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@dataclass
class Job:
    run_dir: str
    argv: list          # tacrl.py's flags: a new run's, or --resume DIR
    state: str          # "new", "resume" or "done"


def plan(experiments, seeds, root, flags=()):
    """The jobs of `experiments` (names of EXPERIMENTS; none: one experiment of `flags`) for each seed, under
    root/<experiment>/<run name> (root/<run name> for `flags`). Each job's command is checked as tacrl.py will
    check it, and a run dir that already holds a run must hold this one, before anything starts."""
    rows = [(name, row) for name in experiments for row in EXPERIMENTS[name]] or [("", list(flags))]
    jobs = []
    for name, row in rows:
        for s in seeds:
            argv = [*row, "--seed", str(s)]
            cfg = config_of(argv)
            jobs.append(job_of(os.path.join(root, name, run_name(cfg)), argv, cfg))
    dirs = [j.run_dir for j in jobs]
    if len(set(dirs)) < len(dirs):
        raise ArgError(f"two runs of the plan would share {next(d for d in dirs if dirs.count(d) > 1)}")
    return jobs


def config_of(argv):
    """tacrl.py's flags -> the run's Config (ArgError for a mistake in them)."""
    return tacrl.Config(**command.with_presets(tacrl.Config, cli.parse(tacrl.Config, argv, "")))


def run_name(cfg):
    """The name of a run's directory under its experiment's folder: tacrl.py's default run dir's."""
    return os.path.basename(command.default_run_dir(cfg))


def job_of(run_dir, argv, cfg):
    """A new run (its flags checked as tacrl.py checks them), the one in run_dir to resume, or one already
    finished; ArgError where run_dir holds another run."""
    if not os.path.exists(os.path.join(run_dir, "config.json")):
        tacrl.parse_args([*argv, "--run-dir", run_dir])       # a mistake in the flags, or a dir not empty
        return Job(run_dir, [*argv, "--run-dir", run_dir], "new")
    try:
        old = tacrl.read_config(run_dir)
    except (OSError, ValueError) as e:
        raise ArgError(f"{run_dir}: a damaged run directory ({cli.describe(e)}); move it away to run it again")
    differ = [k for k, v in vars(cfg).items()
              if k not in (*command.RESUME_MAY_SET, "run_dir", "device") and getattr(old, k) != v]
    if differ:
        raise ArgError(f"{run_dir} holds another run (its {', '.join(differ)} differ): move it away or use another "
                       "--root")
    done = os.path.exists(os.path.join(run_dir, "eval.json"))
    return Job(run_dir, ["--resume", run_dir], "done" if done else "resume")


def job_command(job, threads):
    return [sys.executable, os.path.join(PROJECT, "tacrl.py"), *job.argv, "--threads", str(threads)]


def thread_env(threads):
    """What a run's environment sets: numpy's BLAS and OpenMP get torch's thread count too (Ray sets OMP_NUM_THREADS
    to a task's CPUs since Ray 2.2, PR ray-project/ray#30496; here it is the same everywhere)."""
    return {k: str(threads) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


def run_job(cmd, run_dir, env, cwd, log_name=rundir.LOG):
    """One run in `cwd`, its output appended to its run dir's train.log; its exit code. A run that began already
    (its config.json is there: this is a retry) is resumed from its checkpoint. A run killed by a signal (its
    process, or the machine, gone) raises ChildProcessError, which the sweep retries (Ray: its task retries). It
    reads only the standard library, so that a Ray worker on any node, where this module may not be importable, can
    run it."""
    import os
    import subprocess
    os.makedirs(run_dir, exist_ok=True)
    if "--run-dir" in cmd and os.path.exists(os.path.join(run_dir, "config.json")):   # a new run's command, begun
        cmd = [*cmd[:2], "--resume", run_dir, *cmd[cmd.index("--threads"):]]       # (its --threads kept)
    with open(os.path.join(run_dir, log_name), "a") as log:
        code = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, env={**os.environ, **env}, cwd=cwd).returncode
    if code < 0:
        raise ChildProcessError(f"{run_dir}: killed by signal {-code}")
    return code


KILLED = -9                 # the exit code a run killed every time it was tried is reported with
REASONS = {2: "a mistake in its flags or files", cli.UNWRITABLE: "its run dir could not be written (a full disk, or "
           "read-only): free space, then the same command resumes it", 130: "interrupted",
           KILLED: "killed every time it was tried"}


def reason(code):
    """Why a run failed, by its exit code."""
    return REASONS.get(code, f"exit code {code}")


def last_episode(run_dir):
    """'<episode>/<of>' from a run's log, '-' before its first episode."""
    try:
        with open(os.path.join(run_dir, rundir.LOG)) as f:
            last = [ln for ln in f.read().splitlines() if ln.startswith("ep ")]
    except OSError:
        last = []
    return last[-1].split()[1] if last else "-"


class Progress:
    """A line when a run starts (or is queued) and when it ends, and one a minute with each started run's episode."""

    def __init__(self, todo, log):
        self.t0 = self.shown = time.time()
        self.todo, self.log, self.running = todo, log, []
        self.lock = threading.Lock()    # runs start on pool threads: print writes a line and its newline apart

    def started(self, job, verb="started"):
        with self.lock:
            self.running.append(job)
            self.log(f"{verb} {job.run_dir} ({job.state}), its log {job.run_dir}/{rundir.LOG}")

    def ended(self, job, code, left):
        with self.lock:
            self.running.remove(job)
            self.log(f"[{rundir.fmt_time(time.time() - self.t0)}] {job.run_dir}: "
                     f"{'finished' if code == 0 else f'failed: {reason(code)}'} ({left} of {self.todo} left)")

    def tick(self):
        with self.lock:
            if time.time() - self.shown > 60:
                self.shown = time.time()
                self.log(f"[{rundir.fmt_time(self.shown - self.t0)}] episodes: "
                         + "  ".join(f"{os.path.basename(j.run_dir)} {last_episode(j.run_dir)}" for j in self.running))


def collect(pending, ready_of, result_of, progress):
    """Wait for every pending run ({handle: job}) to end, whichever executor runs it: ready_of(handles) -> those
    ended (waiting a second at most), result_of(handle) -> its exit code; [(job, exit code)]."""
    done = []
    while pending:
        for h in ready_of(list(pending)):
            job = pending.pop(h)
            done.append((job, result_of(h)))
            progress.ended(job, done[-1][1], len(pending))
        progress.tick()
    return done


def run_local(jobs, parallel, threads, log=lambda m: print(m, flush=True), retries=2):
    """The jobs as local processes, at most `parallel` at a time, each waited on by a thread that runs it as a Ray
    task does (run_job), a killed one again from its checkpoint up to `retries` times; [(job, exit code)]."""
    import concurrent.futures as cf
    progress = Progress(len(jobs), log)

    def start(job):
        progress.started(job)
        for attempt in range(retries + 1):
            try:
                return run_job(job_command(job, threads), job.run_dir, thread_env(threads), os.getcwd())
            except ChildProcessError as e:
                log(f"{e}: {'resumed from its checkpoint' if attempt < retries else 'not tried again'} "
                    f"({attempt + 1} of {retries + 1} tries)")
        return KILLED
    with cf.ThreadPoolExecutor(parallel) as pool:
        pending = {pool.submit(start, j): j for j in jobs}
        return collect(pending, lambda fs: cf.wait(fs, timeout=1.0, return_when=cf.FIRST_COMPLETED)[0],
                       lambda f: f.result(), progress)


def run_ray(jobs, address, threads, log=lambda m: print(m, flush=True), init=None, retries=2):
    """The jobs as Ray tasks of `threads` CPUs each (Ray starts as many at once as the CPUs allow), on a local
    instance (address "local") or a running cluster's ("auto", "HOST:6379", "ray://HOST:10001"); [(job, exit
    code)]. A task whose worker dies (a preempted node), or whose run is killed, is retried by Ray up to `retries`
    times (its max_retries, and retry_exceptions for run_job's ChildProcessError), resuming from its checkpoint."""
    try:
        import ray
    except ImportError:
        raise ArgError("--ray needs Ray: pip install -e '.[ray]'")
    if not ray.is_initialized():
        kw = init or ({"num_cpus": os.cpu_count(), "include_dashboard": False} if address == "local"
                      else {"address": address})
        try:
            ray.init(log_to_driver=False, **kw)
        except ConnectionError as e:
            raise ArgError(f"--ray {address}: no Ray cluster there ({cli.describe(e)})")
    # the task travels by value: no module to import there
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    task = ray.remote(num_cpus=threads, max_retries=retries, retry_exceptions=[ChildProcessError])(run_job)
    # paths as here
    pending = {task.remote(job_command(j, threads), j.run_dir, thread_env(threads), os.getcwd()): j for j in jobs}
    progress = Progress(len(jobs), log)
    for j in jobs:
        progress.started(j, "queued")          # Ray starts each when a node has its CPUs free
    def code_of(ref):                          # its exit code; a task that failed every try: killed
        try:
            return ray.get(ref)
        except ray.exceptions.RayError as e:
            log(f"{pending_jobs[ref].run_dir}: not tried again after {retries + 1} tries ({type(e).__name__})")
            return KILLED
    pending_jobs = dict(pending)
    return collect(pending, lambda refs: ray.wait(refs, num_returns=1, timeout=1.0)[0], code_of, progress)


def parse_list(text, what, cast=str):
    try:
        items = [cast(x) for x in text.split(",")]
    except ValueError:
        items = []
    if not items or len(set(items)) != len(items):
        raise ArgError(f"{what} takes distinct comma-separated values, not {text!r}")
    return items


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    flags = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    ap = cli.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("experiments", nargs="?", default="", help=f"comma-separated, of {', '.join(EXPERIMENTS)}; "
                    "or none, and tacrl.py's flags after --")
    ap.add_argument("--seeds", default=",".join(map(str, SEEDS)),
                    help=f"comma-separated training seeds (default: {','.join(map(str, SEEDS))})")
    ap.add_argument("--root", default="runs", help="where the run dirs go (default: runs)")
    ap.add_argument("--parallel", type=int, default=0, help="runs at once, locally (default: one a core)")
    ap.add_argument("--ray", default="", metavar="ADDRESS", help="run as Ray tasks: 'local' (a Ray instance on this "
                    "machine), 'auto' (the cluster this machine is in), or a cluster's address")
    ap.add_argument("--threads", type=int, default=1, help="threads an update of each run, 1 or 2 (default: 1)")
    ap.add_argument("--retries", type=int, default=2, help="times a run that was killed (its process or its machine "
                    "gone) is resumed from its checkpoint (default: 2); a run that failed otherwise is not retried")
    ap.add_argument("--list", action="store_true", help="list the experiments' runs and their state, and stop")
    ap.add_argument("--dry-run", action="store_true", help="print the commands, run nothing")
    a = ap.parse_args(argv)
    names = parse_list(a.experiments, "the experiments") if a.experiments else []
    if a.list and not flags:
        names = names or list(EXPERIMENTS)
    unknown = [n for n in names if n not in EXPERIMENTS]
    if unknown:
        raise ArgError(f"no experiment {unknown[0]!r}; there are {', '.join(EXPERIMENTS)}")
    if bool(names) == bool(flags):
        raise ArgError("name experiments, or give tacrl.py's flags after --, not both or neither "
                       "(python tools/sweep.py --list shows the experiments)")
    if flags and any(f in ("--seed", "--run-dir", "--resume", "--eval", "--threads") or
                     f.split("=")[0] in ("--seed", "--run-dir", "--resume", "--eval", "--threads") for f in flags):
        raise ArgError("the flags after -- are a run's: the sweep sets --seed, --run-dir and --threads itself "
                       "(--eval and --resume are for one run: tacrl.py)")
    if not 1 <= a.threads <= 2 or a.parallel < 0 or a.retries < 0:
        raise ArgError("--threads must be 1 or 2, --parallel and --retries at least 0")
    jobs = plan(names, parse_list(a.seeds, "--seeds", int), a.root, flags)
    todo = [j for j in jobs if j.state != "done"]
    cores = os.cpu_count() or 1
    parallel = a.parallel or max(1, cores // a.threads)      # threads x runs <= cores
    if not a.ray:
        command.warn_oversubscribed("sweep", a.threads, min(parallel, max(1, len(todo))), cores)
    if a.list or a.dry_run:
        for j in jobs:
            print(f"{j.state:6s}  {j.run_dir}" if a.list else
                  ("# done: " if j.state == "done" else "") + " ".join(["python", *job_command(j, a.threads)[1:]]))
        return 0
    print(f"{len(jobs)} runs, {len(jobs) - len(todo)} finished already; {len(todo)} to run "
          + (f"as Ray tasks ({a.ray})" if a.ray else "here"), flush=True)
    if a.ray:
        done = run_ray(todo, a.ray, a.threads, retries=a.retries)
    else:
        done = run_local(todo, parallel, a.threads, retries=a.retries)
    failed = [f"{j.run_dir} ({reason(code)})" for j, code in done if code]
    if failed:
        raise cli.Failed(f"{len(failed)} of {len(todo)} runs failed (see their {rundir.LOG}): {'; '.join(failed)}; "
                         "the same command resumes them")
    return 0


if __name__ == "__main__":
    sys.exit(cli.command("sweep", main))
