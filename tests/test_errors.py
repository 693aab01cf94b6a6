"""A user's mistake, in every mode, is one line naming the flag or file, exit code 2, and changes
nothing on disk; Ctrl-C is one line and exit code 130; a launcher of several runs overwrites none and
says which failed; random flag values come out of the checks as a Config or as one such line."""
import json
import os
import pickle
import shutil
import string
import time
import warnings

import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cli
import baselines
import report
import sim
import tacrl

TINY = ["--task", "peg", "--error-mm", "1", "--train-episodes", "3", "--warmup", "1", "--updates", "2",
        "--batch", "8", "--episodes", "1", "--eval-levels", "1", "--buffer", "40", "--threads", "1"]
# (--threads 1: no second process for the evaluation, whose start-up would cost more than these runs)


def snapshot(root):
    """Every file and folder under root, with each file's size and time of last change (a file written
    again, even with the same bytes, counts as changed)."""
    out = {}
    for d, dirs, files in os.walk(root):
        for name in dirs + files:
            st_ = os.stat(os.path.join(d, name))
            out[os.path.relpath(os.path.join(d, name), root)] = "dir" if name in dirs else (st_.st_size,
                                                                                            st_.st_mtime_ns)
    return out


@pytest.fixture(scope="module")
def unfinished_run(tmp_path_factory):
    """A tiny run that trained its three episodes but was stopped before its evaluation: one to --resume."""
    run_dir = str(tmp_path_factory.mktemp("errors") / "run")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sim, "MAX_STEPS", 9)
        tacrl.train(tacrl.parse_args(TINY + ["--run-dir", run_dir]), log=lambda *_: None)
    os.remove(os.path.join(run_dir, "eval.json"))
    return run_dir


@pytest.fixture(scope="module")
def workdir(tmp_path_factory, unfinished_run):
    """A working directory with the things the mistakes below point at (shared: none may change it)."""
    tmp_path = tmp_path_factory.mktemp("here")
    (tmp_path / "afile").write_text("a file")
    (tmp_path / "adir").mkdir()
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "notes.txt").write_text("someone's")
    (tmp_path / "adir.webm").mkdir()
    (tmp_path / "row.json").write_text("{}")
    (tmp_path / "empty.pt").write_bytes(b"")
    (tmp_path / "pickled.pt").write_bytes(pickle.dumps({"task": "peg"}))     # a pickle, not torch's zip format
    torch.save({"task": "peg"}, tmp_path / "notapolicy.pt")                   # torch's format, not a policy
    for name, config in (("badtype", '{"episodes": "x"}'), ("notjson", "{task: peg"), ("badchoice", '{"task": '
                                                                                                    '"screw"}'),
                         ("notobject", "[1, 2]"), ("null", "null")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "config.json").write_text(config)
    (tmp_path / "cfgdir" / "config.json").mkdir(parents=True)
    for name in ("run", "emptyckpt", "badreplay", "noreplay", "nometrics", "badmetrics"):
        shutil.copytree(unfinished_run, tmp_path / name)
    (tmp_path / "emptyckpt" / "ckpt.pt").write_bytes(b"")
    replay = sorted(os.listdir(tmp_path / "badreplay" / "replay"))
    (tmp_path / "badreplay" / "replay" / replay[-1]).write_bytes(b"PK\x03\x04 truncated")
    shutil.rmtree(tmp_path / "noreplay" / "replay")
    os.remove(tmp_path / "nometrics" / "metrics.csv")
    (tmp_path / "badmetrics" / "metrics.csv").write_text("episode,return\n1,x\n")
    return tmp_path


@pytest.fixture
def here(workdir, monkeypatch):
    monkeypatch.chdir(workdir)
    monkeypatch.setattr(sim, "MAX_STEPS", 9)                  # TINY's 40-transition buffer holds an episode
    monkeypatch.delenv("DISPLAY", raising=False)
    return workdir


def mistake(argv, here, capsys, main=tacrl.main, prog="tacrl"):
    """Run a command that must refuse: returns its one line."""
    before = snapshot(here)
    capsys.readouterr()
    with warnings.catch_warnings(record=True) as caught:     # a library's warning would print above our line
        warnings.simplefilter("always")
        assert main(argv) == 2, argv
    assert not caught, [str(w.message)[:200] for w in caught]
    err = capsys.readouterr().err
    assert err.startswith(f"{prog}: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    assert snapshot(here) == before, "the refused command changed files on disk"
    return err


MISTAKES = {   # a few of each kind; the files they point at are in `workdir`
    "numbers out of range or not numbers": [["--lr", "nan"], ["--seed", "-1"], ["--buffer", "29"],
                                            ["--eval-levels", "25"]],
    "a run dir that is a file, unwritable, someone else's or a run": [["--run-dir", "afile"],
                                                                      ["--run-dir", "/proc/tacrl-run"],
                                                                      ["--run-dir", "full"], ["--run-dir", "run"]],
    "--resume of what is not a run": [["--resume", "adir"], ["--resume", "notjson"], ["--resume", "notobject"],
                                      ["--resume", "badtype"]],
    "--resume of a damaged run": [["--resume", "emptyckpt"], ["--resume", "badreplay"], ["--resume", "nometrics"]],
    "--resume with flags it cannot honour": [["--resume", "run", "--lr", "0.1"],
                                             ["--resume", "run", "--train-episodes", "1"]],
    "a policy file that is not one, or not for this": [["--eval", "empty.pt"], ["--eval", "pickled.pt"],
                                                        ["--eval", "emptyckpt/ckpt.pt"],
                                                        ["--eval", "run/policy.pt", "--error-mm", "25"]],
    "a file to write that exists or cannot be written": [["--eval", "initial", "--json", "row.json"],
                                                         ["--eval", "initial", "--video", "no/such/ep.webm"],
                                                         ["--eval", "initial", "--json", "/proc/row.json"]],
    "a flag of the other mode, or one that would change nothing": [["--eval", "initial", "--lr", "0.1"],
                                                                   ["--json", "x.json"], ["--train-episode", "5"]],
    "a window without a display": [["--eval", "initial", "--gui"]],
}


@pytest.mark.parametrize("argv", [a for kind in MISTAKES.values() for a in kind])
def test_a_mistake_is_one_line_naming_its_flag_exit_2_and_changes_nothing(argv, here, capsys):
    t0 = time.time()
    err = mistake(argv, here, capsys)
    assert any(flag in err for flag in argv if flag.startswith("--")), err
    assert time.time() - t0 < 60     # no hang (--gui without a display once hung for good); not a speed test: a
                                     # refused --resume builds the env first, 4-10 s beside one busy process


def test_ctrl_c_in_the_two_step_calibration_is_one_line_and_exit_130(here, capsys, monkeypatch):
    def interrupted(self, *a, **kw):
        raise KeyboardInterrupt
    monkeypatch.setattr(baselines.TwoStep, "calibrate", interrupted)
    assert tacrl.main(["--eval", "two-step"]) == 130
    err = capsys.readouterr().err
    assert err.strip().startswith("tacrl:") and "\n" not in err.strip()


def test_ctrl_c_while_training_says_how_to_resume(here, tmp_path, capsys, monkeypatch):
    def interrupted(*a, **kw):
        raise KeyboardInterrupt
    monkeypatch.chdir(tmp_path)                               # this one writes a run dir
    monkeypatch.setattr(tacrl, "rollout", interrupted)
    assert tacrl.main(TINY + ["--run-dir", "new"]) == 130
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.endswith("--resume new")         # what continues it


def test_report_and_archive_mistakes(here, tmp_path, capsys, monkeypatch, unfinished_run):
    run = lambda *argv: cli.command("report", lambda: report.main(list(argv)))   # noqa: E731
    monkeypatch.chdir(tmp_path)
    for name in ("afile", "badtype", "run"):
        shutil.copytree(here / name, name) if name != "afile" else shutil.copy(here / name, name)
    before = snapshot(tmp_path)
    for argv, names in ((["run", "--out", "afile"], "--out 'afile'"), (["no/such/*"], "no/such/*"),
                        (["badtype"], "badtype"), (["run", "--archive"], "'run'")):
        assert run(*argv) == 2
        err = capsys.readouterr().err
        assert names in err and err.count("\n") == 1, (argv, err)     # the flag or path at fault, in one line
    shutil.copy(os.path.join(unfinished_run, "metrics.csv"), "badtype/metrics.csv")   # a run dir, badly configured
    assert run("badtype") == 2 and "badtype" in capsys.readouterr().err
    os.remove("badtype/metrics.csv")
    assert snapshot(tmp_path) == before
    # archiving onto another run of the same name copies nothing
    os.makedirs("results/run")
    with open("results/run/config.json", "w") as f:
        f.write("{}")
    with open("run/eval.json", "w") as f:
        json.dump({"rows": []}, f)
    before = snapshot(tmp_path)
    assert run("run", "--archive", "--to", "results") == 2
    assert "'results/run'" in capsys.readouterr().err and snapshot(tmp_path) == before


FLAGS = {"--task": st.sampled_from(["peg", "gear", "screw", ""]), "--error-mm": st.floats(allow_nan=True),
         "--seed": st.integers(-5, 2 ** 33), "--lr": st.floats(), "--gamma": st.floats(-1, 2),
         "--batch": st.integers(-2, 100), "--buffer": st.integers(-2, 300), "--episodes": st.integers(-2, 5),
         "--eval-levels": st.text(string.digits + ",.-x", max_size=8), "--roi": st.sampled_from(["task", "full", "x"]),
         "--eval": st.sampled_from(["initial", "two-step", "nope.pt", ""]),
         "--run-dir": st.sampled_from(["afile", "adir", "new", "/proc/x", ""]),
         "--json": st.sampled_from(["row.json", "new.json", "adir"]), "--clearance-mm": st.floats(-1, 3),
         "--threads": st.integers(-2, 4), "--warmup": st.integers(-2, 30), "--context": st.text(max_size=6)}


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(flags=st.dictionaries(st.sampled_from(sorted(FLAGS)), st.none(), max_size=6).flatmap(
    lambda keys: st.fixed_dictionaries({k: FLAGS[k] for k in keys})))
def test_random_flag_values_give_a_checked_config_or_one_line(flags, here):
    argv = [x for k, v in flags.items() for x in (k, str(v))]
    before = snapshot(here)
    try:
        cfg = tacrl.parse_args(argv)
    except cli.ArgError as e:
        assert "\n" not in str(e) and str(e)
    else:                                   # what got through is what the flags promise
        assert cfg.task in ("peg", "gear") and 0 <= cfg.error_mm <= 30 and 0 < cfg.lr < 1 and 0 < cfg.gamma < 1
        assert cfg.seed >= 0 and cfg.buffer >= max(cfg.batch, sim.MAX_STEPS) and cfg.episodes >= 1
    assert snapshot(here) == before


def test_the_objects_and_touch_studies_refuse_mistakes_in_one_line(tmp_path, capsys):
    import objects
    import touch
    cases = ((objects, []), (objects, [str(tmp_path / "none*")]), (objects, ["x", "--episodes", "0"]),
             (objects, ["--docs", str(tmp_path), "--out", str(tmp_path / "empty")]),
             (touch, [str(tmp_path / "none")]), (touch, [str(tmp_path), "--episodes", "0"]),
             (touch, ["initial", "--error-mm", "0"]), (touch, ["initial", "--held-out", "--error-mm", "25"]),
             (touch, [str(tmp_path), "--held-out", "--task", "gear"]), (touch, ["initial", "--family", "colour"]),
             (touch, ["initial", "--held-out", "--family", "paint"]),
             (touch, [str(tmp_path), "--views", str(tmp_path)]),
             (touch, ["initial", "--held-out", "--views", str(tmp_path)]))
    for mod, argv in cases:
        assert cli.command(mod.__name__, lambda: mod.main(argv)) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"{mod.__name__}: error:"), (argv, err)
