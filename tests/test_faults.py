"""What a long run meets on shared machines, and what it does then: a disk that fills or turns read-only mid-run
(one line, exit code 74, the last complete checkpoint whole, and --resume after space is freed gives the run an
uninterrupted one gives); a second process started on the same run dir (refused in one line, the first's files
untouched); a truncated checkpoint, replay file or metrics.csv (refused in one line naming it, or read back to the
last good state)."""
import csv
import errno
import json
import os
import shutil
import subprocess

import pytest

import rundir
import sim
import tacrl

TINY = ["--task", "peg", "--error-mm", "1", "--train-episodes", "4", "--warmup", "1", "--updates", "2",
        "--batch", "8", "--episodes", "1", "--eval-levels", "1", "--buffer", "40", "--threads", "1"]
STEPS = 9            # an episode's, not 120: the untrained policy runs each to the limit
TIMES = ("env_s", "update_s", "elapsed_s")


def rows_of(run_dir):
    """metrics.csv without its times, and eval.json without its minutes: what a run computed."""
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        rows = [{k: v for k, v in r.items() if k not in TIMES} for r in csv.DictReader(f)]
    ev = json.loads(open(os.path.join(run_dir, "eval.json")).read())
    return rows, {k: v for k, v in ev.items() if k != "train_minutes"}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """TINY trained with nothing in its way."""
    run_dir = str(tmp_path_factory.mktemp("faults") / "whole")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sim, "MAX_STEPS", STEPS)
        tacrl.train(tacrl.parse_args(TINY + ["--run-dir", run_dir]), log=lambda *_: None)
    return rows_of(run_dir)


def small_disk(path, size):
    """A tmpfs of `size` (e.g. '6m') mounted at path, where this process may mount one; else None."""
    os.makedirs(path)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], capture_output=True)
    return str(path) if r.returncode == 0 else None


@pytest.mark.parametrize("fault", ["full", "read-only"])
def test_a_disk_that_fills_or_turns_read_only_stops_the_run_in_one_line_and_resume_finishes_it(
        fault, tmp_path, monkeypatch, capsys, reference):
    monkeypatch.setattr(sim, "MAX_STEPS", STEPS)
    disk = small_disk(tmp_path / "disk", "8m" if fault == "full" else "64m")    # 8m: a checkpoint and a half
    saves = []
    real_save = rundir.Run.save

    def save(run, *a, **kw):                 # the fault comes after episode 2's checkpoint
        if len(saves) == 2:
            if disk and fault == "read-only":
                subprocess.run(["mount", "-o", "remount,ro", disk], check=True)
            elif not disk:                   # no mount here: the write fails as a full disk's does
                monkeypatch.setattr(rundir, "replace_atomic", lambda path, *_, **__: (_ for _ in ()).throw(
                    OSError(errno.ENOSPC if fault == "full" else errno.EROFS, "no space", path)))
        saves.append(1)
        return real_save(run, *a, **kw)
    monkeypatch.setattr(rundir.Run, "save", save)
    run_dir = os.path.join(disk or str(tmp_path), "run")
    try:
        assert tacrl.main(TINY + ["--run-dir", run_dir]) == 74
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err and f"--resume {run_dir}" in err
        assert not os.path.exists(os.path.join(run_dir, "eval.json"))
        assert not [f for f in os.listdir(run_dir) if f.endswith(".tmp")]          # no half-written file is left
        episode = int(rundir.load_file(os.path.join(run_dir, "ckpt.pt"))["episode"])   # the last complete one
        assert 1 <= episode < 4
        if disk:                             # space freed, or the file system writable again
            subprocess.run(["mount", "-o", "remount,rw,size=64m", disk], check=True)
        monkeypatch.undo()
        monkeypatch.setattr(sim, "MAX_STEPS", STEPS)
        assert tacrl.main(["--resume", run_dir]) == 0
        assert rows_of(run_dir) == reference                                      # as if nothing had happened
    finally:
        if disk:
            subprocess.run(["umount", disk])


def test_a_second_writer_of_a_run_dir_is_refused_in_one_line_and_changes_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sim, "MAX_STEPS", STEPS)
    run_dir = str(tmp_path / "run")
    assert tacrl.main(TINY + ["--run-dir", run_dir, "--train-episodes", "2"]) == 0
    os.remove(os.path.join(run_dir, "eval.json"))               # as if still training: one to --resume
    capsys.readouterr()
    first = rundir.lock(run_dir)                                # the first writer, still at work
    try:
        before = {f: os.stat(os.path.join(run_dir, f)).st_mtime_ns for f in os.listdir(run_dir)}
        for argv in (["--resume", run_dir], TINY + ["--run-dir", run_dir]):
            assert tacrl.main(argv) == 2
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and run_dir in err and ("--resume" in err or "--run-dir" in err), err
        assert {f: os.stat(os.path.join(run_dir, f)).st_mtime_ns for f in os.listdir(run_dir)} == before
    finally:
        os.close(first)
    assert tacrl.main(["--resume", run_dir]) == 0               # the first gone, the run goes on


@pytest.fixture(scope="module")
def stopped(tmp_path_factory):
    """A tiny run stopped after its 3rd episode: ckpt.pt, metrics.csv and replay/ of 3 episodes."""
    run_dir = str(tmp_path_factory.mktemp("faults") / "stopped")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sim, "MAX_STEPS", STEPS)
        tacrl.train(tacrl.parse_args(TINY + ["--run-dir", run_dir, "--train-episodes", "3"]), log=lambda *_: None)
    os.remove(os.path.join(run_dir, "eval.json"))
    return run_dir


def truncate(path, keep=0.5):
    with open(path, "rb") as f:
        data = f.read()
    with open(path, "wb") as f:
        f.write(data[:int(len(data) * keep)])


@pytest.mark.parametrize("damaged", ["ckpt.pt", "replay/ep_000003.npz", "metrics.csv"])
def test_a_truncated_file_is_refused_in_one_line_naming_it(damaged, stopped, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sim, "MAX_STEPS", STEPS)
    run_dir = str(tmp_path / "run")
    shutil.copytree(stopped, run_dir)
    truncate(os.path.join(run_dir, damaged))
    before = {f: os.stat(os.path.join(run_dir, f)).st_mtime_ns for f in ("ckpt.pt", "metrics.csv")}
    assert tacrl.main(["--resume", run_dir, "--train-episodes", "4"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and os.path.basename(damaged) in err, err
    assert {f: os.stat(os.path.join(run_dir, f)).st_mtime_ns for f in ("ckpt.pt", "metrics.csv")} == before


def test_a_row_cut_short_past_the_checkpoint_is_dropped_and_the_run_resumes(stopped, tmp_path, monkeypatch,
                                                                             reference):
    # a full disk in the middle of episode 4's row: the checkpoint is episode 3's, so that row is not the run's
    monkeypatch.setattr(sim, "MAX_STEPS", STEPS)
    run_dir = str(tmp_path / "run")
    shutil.copytree(stopped, run_dir)
    with open(os.path.join(run_dir, "metrics.csv"), "a") as f:
        f.write("4,-12.5,0,0.25")
    assert tacrl.main(["--resume", run_dir, "--train-episodes", "4"]) == 0
    assert rows_of(run_dir) == reference
