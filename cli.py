"""cli.py: what every command of tacrl shares (tacrl.py, tools/): flags declared once as config fields (opt),
parsed with no abbreviation, checked against their bounds, and read back from a run's JSON; a user's mistake as
one line and exit code 2 (ArgError), failed work as exit code 1 (Failed), a write that failed as 74 (Unwritable),
Ctrl-C as 130 (command); and the checks that a command can write where it will, before any work. It imports nothing
of tacrl.
"""
import argparse
import dataclasses
import errno
import math
import os
import signal
import sys
import tempfile


class ArgError(Exception):
    """A user's mistake: one line naming the flag or file and what is wrong, exit code 2, before any work."""


class Failed(Exception):
    """Work that was started and failed (a training run of tools/sweep.py): one line, exit code 1."""


class Unwritable(Exception):
    """A write that failed mid-run (a full disk, a read-only file system): one line, exit code 74 (sysexits.h's
    EX_IOERR), which tools/sweep.py reports by name and does not retry."""


UNWRITABLE = 74
WRITE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EIO, errno.EFBIG)


def opt(default, help, choices=None, mode=None, bounds=None, open_bounds=False):
    """A Config field that is a flag: its default, --help text, allowed values or bounds (lo, hi; None for no
    bound; within them or, with open_bounds, strictly), and the mode it is for (None: every mode)."""
    return dataclasses.field(default=default, metadata={"help": help, "choices": choices, "mode": mode,
                                                        "bounds": bounds, "open": open_bounds})


class Parser(argparse.ArgumentParser):
    """argparse, but a mistake is an ArgError (one line, no usage dump) and no flag may be abbreviated
    (a typo of one flag must not pass as another)."""

    def __init__(self, **kw):
        super().__init__(allow_abbrev=False, **kw)

    def error(self, message):
        raise ArgError(message)


def parse(config_cls, argv, description):
    """argv -> {field name: value} of the flags given (not the defaults: the caller can tell what the
    user asked for), through a Parser built from config_cls's opt() fields; floats must be finite. --help lists
    them under config_cls.GROUPS' titles where it has them ({title: field names}, every field in one)."""
    ap = Parser(description=description, usage="%(prog)s [flags of the groups below]",
                formatter_class=argparse.RawDescriptionHelpFormatter)     # (the description's lines as written)
    for title, names in groups_of(config_cls).items():
        section = ap.add_argument_group(title) if title else ap
        for f in (f for f in dataclasses.fields(config_cls) if f.name in names):
            flag = "--" + f.name.replace("_", "-")
            lo, hi = f.metadata["bounds"] or (None, None)
            bounds = "" if f.metadata["bounds"] is None else \
                f"; {lo if lo is not None else ''}..{hi if hi is not None else ''}"
            hlp = f.metadata["help"] + (f" (default: {f.default}{bounds})" if f.default not in ("", False) else "")
            if f.type is bool:
                section.add_argument(flag, action="store_true", default=argparse.SUPPRESS, help=hlp)
            else:                          # (a long list of choices: the help names them, the usage line not)
                choices = f.metadata["choices"]
                long = choices is not None and len(",".join(choices)) > 60
                section.add_argument(flag, type=finite_float if f.type is float else f.type,
                                     default=argparse.SUPPRESS, choices=choices, help=hlp,
                                     metavar=f.name.upper() if long else None)
    return vars(ap.parse_args(argv))


def groups_of(config_cls):
    """config_cls.GROUPS ({title: field names}), checked to hold every field once; {'': all} where it has none."""
    names = [f.name for f in dataclasses.fields(config_cls)]
    groups = getattr(config_cls, "GROUPS", None) or {"": tuple(names)}
    grouped = [n for g in groups.values() for n in g]
    if sorted(grouped) != sorted(names):
        raise TypeError(f"{config_cls.__name__}.GROUPS must hold each field once: "
                        f"{sorted(set(names) ^ set(grouped)) or 'some twice'}")
    return groups


def format_config(cfg, width=110):
    """The config as a reader takes it in: a line a group of config_cls.GROUPS (its title before any bracket), its
    flags as they are typed (`--error-mm 20`), wrapped at `width`; a flag that is off (false, or '') is left out."""
    groups = {title.split(" (")[0] or "flags": names for title, names in groups_of(type(cfg)).items()}
    indent = 2 + max(map(len, groups)) + 2
    lines = ["config:"]
    for title, names in groups.items():
        line = f"  {title}".ljust(indent - 1)
        for n in names:
            v = getattr(cfg, n)
            if v is False or v == "":
                continue
            word = f"--{n.replace('_', '-')}" + ("" if v is True else f" {v:g}" if isinstance(v, float) else f" {v}")
            if len(line) + 1 + len(word) > width and line.strip():
                lines.append(line)
                line = " " * (indent - 1)
            line += " " + word
        lines.append(line)
    return "\n".join(lines)


def check_bounds(cfg):
    """Every opt() field of cfg within its bounds, else an ArgError naming the flag."""
    for f in dataclasses.fields(cfg):
        lo, hi = f.metadata["bounds"] or (None, None)
        v, strict = getattr(cfg, f.name), f.metadata["open"]
        if (lo is not None and (v <= lo if strict else v < lo)) or (hi is not None and (v >= hi if strict else v > hi)):
            where = f"at least {lo}" if hi is None else f"at most {hi}" if lo is None else \
                f"within {'(' if strict else ''}{lo}..{hi}{')' if strict else ''}"
            raise ArgError(f"--{f.name.replace('_', '-')} must be {where}, not {v}")


def from_dict(config_cls, d):
    """A config_cls from a dict read from a file: every key a field, every value of its field's type
    (an int for a float is fine) and among its choices; ValueError naming the first that is not."""
    if not isinstance(d, dict):
        raise ValueError("not a JSON object")
    fields_ = {f.name: f for f in dataclasses.fields(config_cls)}
    for k, v in d.items():
        f = fields_.get(k)
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


def finite_float(text):
    """argparse type: a float that is a number (nan and inf are not)."""
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}")
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"not a finite number: {text!r}")
    return x


def command(prog, fn):
    """Run fn() as the command `prog`; returns its exit code: 0, 2 for an ArgError, 1 for Failed, 130 for Ctrl-C,
    each with its one line. From here Ctrl-C is a KeyboardInterrupt again (the scripts make it a plain exit
    while their imports load), so that fn can say what is saved."""
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
    except Unwritable as e:
        print(f"{prog}: stopped: {e}", file=sys.stderr)
        return UNWRITABLE
    except KeyboardInterrupt as e:
        print(f"\n{prog}: interrupted" + (f": {e}" if str(e) else ""), file=sys.stderr)
        return 130


def describe(e):
    """An exception as a short phrase for a one-line message (its type, and its first line if any)."""
    lines = str(e).strip().splitlines()
    return f"{type(e).__name__}: {lines[0][:120]}" if lines else type(e).__name__


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
