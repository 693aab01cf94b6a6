"""cli.py: the command-line plumbing that tacrl.py, report.py and seeds.py share. A user's mistake is
one line naming the flag or file and what is wrong, with exit code 2; a run that fails is one line
and exit code 1; Ctrl-C is one line and exit code 130. The files a command will write are checked
before any work starts, and none that the user already has is overwritten. Standard library only.
"""
import argparse
import csv
import dataclasses
import math
import os
import re
import signal
import sys
import tempfile
import time


LOG = "train.log"            # a training run's console output, which seeds.py writes into its run dir


class ArgError(Exception):
    """A user's mistake: one line, exit code 2."""


class Failed(Exception):
    """Work that was started and failed (a training run of seeds.py): one line, exit code 1."""


class Parser(argparse.ArgumentParser):
    """argparse, but a mistake is an ArgError (one line, no usage dump) and no flag may be abbreviated
    (a typo of one flag must not pass as another)."""

    def __init__(self, **kw):
        super().__init__(allow_abbrev=False, **kw)

    def error(self, message):
        raise ArgError(message)


def opt(default, help, choices=None, mode=None, bounds=None, open_bounds=False):
    """A dataclass field that is a flag: its default, --help text, allowed values or bounds (lo, hi), None
    for no bound, within them or, with open_bounds, strictly), and the mode it is for (None: every mode).
    Each flag is described here and nowhere else."""
    return dataclasses.field(default=default, metadata={"help": help, "choices": choices, "mode": mode,
                                                        "bounds": bounds, "open": open_bounds})


def check_bounds(cfg):
    """Every opt() field of cfg within its bounds, else an ArgError naming the flag."""
    for f in dataclasses.fields(cfg):
        lo, hi = f.metadata["bounds"] or (None, None)
        v, strict = getattr(cfg, f.name), f.metadata["open"]
        if (lo is not None and (v <= lo if strict else v < lo)) or (hi is not None and (v >= hi if strict else v > hi)):
            where = f"at least {lo}" if hi is None else f"at most {hi}" if lo is None else \
                f"within {'(' if strict else ''}{lo}..{hi}{')' if strict else ''}"
            raise ArgError(f"--{f.name.replace('_', '-')} must be {where}, not {v}")


def parse(config_cls, argv, description):
    """argv -> {field name: value} of the flags given (not the defaults: the caller can tell what the
    user asked for), through a Parser built from config_cls's opt() fields; floats must be finite."""
    ap = Parser(description=description)
    for f in dataclasses.fields(config_cls):
        flag = "--" + f.name.replace("_", "-")
        lo, hi = f.metadata["bounds"] or (None, None)
        bounds = "" if f.metadata["bounds"] is None else f"; {lo if lo is not None else ''}..{hi if hi is not None else ''}"
        hlp = f.metadata["help"] + (f" (default: {f.default}{bounds})" if f.default not in ("", False) else "")
        if f.type is bool:
            ap.add_argument(flag, action="store_true", default=argparse.SUPPRESS, help=hlp)
        else:
            ap.add_argument(flag, type=finite_float if f.type is float else f.type, default=argparse.SUPPRESS,
                            choices=f.metadata["choices"], help=hlp)
    return vars(ap.parse_args(argv))


def from_dict(config_cls, d):
    """A config_cls from a dict read from a file: every key a field, every value of its field's type
    (an int for a float is fine) and among its choices; ValueError naming the first that is not."""
    if not isinstance(d, dict):
        raise ValueError("not a JSON object")
    fields = {f.name: f for f in dataclasses.fields(config_cls)}
    for k, v in d.items():
        f = fields.get(k)
        if f is None:
            raise ValueError(f"{k!r} is not a flag")
        if f.type is float and type(v) is int:
            d[k] = v = float(v)
        if type(v) is not f.type or (f.type is float and not math.isfinite(v)):
            kind = {int: "an integer", float: "a finite number", str: "a string", bool: "true or false"}[f.type]
            raise ValueError(f"{k!r} is {v!r}, not {kind}")
        if f.metadata["choices"] and v not in f.metadata["choices"]:
            raise ValueError(f"{k!r} is {v!r}, not one of {', '.join(f.metadata['choices'])}")
    return config_cls(**d)


def command(prog, fn):
    """Run fn() as the command `prog`; returns its exit code. From here Ctrl-C is a KeyboardInterrupt
    again (the scripts make it a plain exit while their imports load), so that fn can say what is saved."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        fn()
        return 0
    except ArgError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except Failed as e:
        print(f"{prog}: failed: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as e:
        print(f"\n{prog}: interrupted" + (f": {e}" if str(e) else ""), file=sys.stderr)
        return 130


def warn_oversubscribed(prog, threads, processes=1, cores=None):
    """A warning line on stderr where `processes` runs of `threads` torch threads each ask for more threads
    than there are cores: on 2 cores, two runs with 2 threads each slowed an update phase from 6 s to 231 s."""
    cores = cores or os.cpu_count() or 1
    if threads * processes > cores:
        print(f"{prog}: warning: {processes} x {threads} torch threads on {cores} cores: they will wait on each "
              f"other (use --threads {max(1, cores // processes)})", file=sys.stderr)


class CoreShare:
    """The cores that other processes leave this one, measured: all CPU time the machine spent (Linux's
    /proc/stat) less this process's own (os.times), over the time since the last call. With torch's
    default of a thread a core, one other busy process slowed SAC updates 3-4x on 2 cores (OpenMP's
    threads wait for each other at every operation, and one of them is always waiting for the core the
    other process holds); with one thread fewer, not at all (bench/bench_threads.py). Where /proc/stat
    cannot be read, every core counts as free."""

    def __init__(self, fixed=0, cores=None):
        self.fixed, self.cores = fixed, cores or os.cpu_count() or 1
        self.last = self._read()

    @staticmethod
    def _read():
        try:
            with open("/proc/stat") as f:
                j = [int(x) for x in f.readline().split()[1:9]]    # user nice system idle iowait irq softirq steal
        except (OSError, ValueError):
            return None
        own = os.times()
        return time.monotonic(), (sum(j) - j[3] - j[4]) / os.sysconf("SC_CLK_TCK"), own.user + own.system

    def free(self):
        """Cores free of other processes since the last call: a core counts as taken once they use 0.3 of it.
        With `fixed` threads (the user's --threads), always that."""
        now = self._read()
        if self.fixed:
            return self.fixed
        if now is None or self.last is None or now[0] - self.last[0] < 0.05:
            return self.cores
        others = ((now[1] - self.last[1]) - (now[2] - self.last[2])) / (now[0] - self.last[0])
        self.last = now
        return max(1, min(self.cores, int(self.cores - others + 0.3)))

    def steps(self, n, set_threads, every=20):
        """range(n), calling set_threads(self.free()) before the first step and every `every` steps: a long
        phase of torch work (an episode's updates) follows the machine as it changes."""
        for i in range(n):
            if i % every == 0:
                set_threads(self.free())
            yield i


def read_log(path, columns, upto):
    """The first `upto` rows of a CSV log of numbered episodes (none for upto 0); ValueError where the log
    has not got them all, in these columns."""
    if not upto:
        return []
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        rows = [r for r in reader if int(r["episode"]) <= upto]
    if reader.fieldnames != columns or [int(r["episode"]) for r in rows] != list(range(1, upto + 1)):
        raise ValueError(f"{os.path.basename(path)}'s rows are not episodes 1-{upto} of this version's columns")
    return rows


def write_log(path, columns, rows):
    with open(path, "w", newline="") as f:
        csv.DictWriter(f, columns).writeheader()
        csv.DictWriter(f, columns).writerows(rows)


def is_evaluation(name):
    """A run dir's file that holds an evaluation of its policy: eval.json and every cached eval*.json."""
    return name.startswith("eval") and name.endswith(".json")


def set_aside(run_dir, episode):
    """Rename what a finished run's policy made (policy.pt, curves.png, eval.json and every evaluation cached
    as eval*.json) to NAME-ep<episode>.EXT when the run is extended, so that its new policy is evaluated
    anew; files set aside before stay as they are."""
    for name in sorted(os.listdir(run_dir)):
        stem, ext = os.path.splitext(name)
        if name in ("policy.pt", "curves.png") or (is_evaluation(name) and not re.search(r"-ep\d+$", stem)):
            os.replace(os.path.join(run_dir, name), os.path.join(run_dir, f"{stem}-ep{episode}{ext}"))


def set_aside_at(run_dir):
    """The episodes at which set_aside kept a run's earlier policies (its eval-epN.json), oldest first."""
    return sorted(int(m[1]) for m in (re.fullmatch(r"eval-ep(\d+)\.json", f) for f in os.listdir(run_dir)) if m)


def fmt_time(s):
    """Seconds as 1h02m or 3m07s."""
    s = int(s)
    return f"{s // 3600}h{s // 60 % 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


def describe(e):
    """An exception as a short phrase for a one-line message (its type, and its first line if any)."""
    lines = str(e).strip().splitlines()
    return f"{type(e).__name__}: {lines[0][:120]}" if lines else type(e).__name__


def finite_float(text):
    """argparse type: a float that is a number (nan and inf are not)."""
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}")
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"not a finite number: {text!r}")
    return x


def can_write_in(folder):
    """Whether a file can be created in this existing folder: tried, not guessed (os.access says yes to
    root even where nothing can be written, such as /proc)."""
    try:
        fd, probe = tempfile.mkstemp(dir=folder, prefix=".tacrl-probe-")
    except OSError:
        return False
    os.close(fd)
    os.remove(probe)
    return True


def check_dir_writable(path, what):
    """`path` is a directory we may write in, or one we could create (its nearest existing parent is
    a writable directory). Leaves nothing behind."""
    p = os.path.abspath(path)
    if os.path.exists(p) and not os.path.isdir(p):
        raise ArgError(f"{what} {path!r} is a file, not a directory")
    while not os.path.exists(p):
        p = os.path.dirname(p)
    if not os.path.isdir(p):
        raise ArgError(f"{what} {path!r}: {p!r} is a file, not a directory")
    if not can_write_in(p):
        raise ArgError(f"{what} {path!r}: nothing can be written in {p!r}")


def check_new_file(path, what):
    """`path` names a file that does not exist yet, in a writable directory that exists: a command that
    will write it can, and overwrites nothing. Leaves nothing behind."""
    if os.path.isdir(path):
        raise ArgError(f"{what} {path!r} is a directory, not a file")
    if os.path.lexists(path):
        raise ArgError(f"{what} {path!r} exists: it would be overwritten (remove it or name another file)")
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        raise ArgError(f"{what} {path!r}: its folder {parent!r} does not exist")
    if not can_write_in(parent):
        raise ArgError(f"{what} {path!r}: nothing can be written in {parent!r}")
