"""tools/sweep.py: the report's experiments as a plan of independent, resumable runs, run as local
processes and as Ray tasks on a local Ray instance (the `ray` extra, which the test extra brings)."""
import os
import sys
from dataclasses import asdict

import pytest

import cli
import rundir
import sweep
import tacrl

TINY = ["--task", "peg", "--error-mm", "1", "--train-episodes", "2", "--warmup", "1", "--updates", "2", "--batch", "8",
        "--episodes", "1", "--eval-levels", "1", "--buffer", "240", "--stop-held", "0"]


def test_every_row_of_an_experiment_trains_the_same_budget_in_a_run_dir_of_its_own():
    jobs = sweep.plan(list(sweep.EXPERIMENTS), [0, 1, 2], "runs")
    assert len({j.run_dir for j in jobs}) == len(jobs) and all(j.state == "new" for j in jobs)
    for name, rows in sweep.EXPERIMENTS.items():
        budgets = {tuple(cli.parse(tacrl.Config, r, "").get(k) for k in ("train_episodes", "stop_held")) for r in rows}
        assert len(budgets) == 1, name
    table1 = [j.run_dir for j in jobs if j.run_dir.startswith(os.path.join("runs", "table1"))]
    assert len(table1) == 12 and all(any(k in d for d in table1) for k in ("vanilla", "-v-", "-ts-ptk-"))

REAL_COMMAND = sweep.job_command


def stand_in(job, threads):
    """A run's command as the sweep builds it, checked as tacrl.py checks it, and a stand-in that runs in a blink
    (the README's command and the fixtures of test_train run tacrl.py itself)."""
    cmd = REAL_COMMAND(job, threads)
    assert cmd[:2] == [sys.executable, os.path.join(sweep.PROJECT, "tacrl.py")]
    assert cmd[-2:] == ["--threads", str(threads)]
    if job.state == "new":
        assert tacrl.parse_args(cmd[2:]).run_dir == job.run_dir
    return [sys.executable, "-c", f"import os; print('ep', {job.state!r}, os.environ['OMP_NUM_THREADS'])"]


def test_the_leave_one_out_takes_each_part_of_the_option_out_once_and_changes_nothing_else():
    full = asdict(sweep.config_of(sweep.FLAGS(sweep.OPTION)))
    parts = [*full["randomize"].split(","), "image_norm", "tilt_deg"]
    outs = []
    for named, flags in sweep.leave_one_out().items():
        cfg = asdict(sweep.config_of(flags))
        changed = [k for k in full if cfg[k] != full[k]]
        assert len(changed) == 1, changed
        gone = set(full["randomize"].split(",")) - set(cfg["randomize"].split(","))
        outs += list(gone) if changed == ["randomize"] else changed
        assert outs[-1] == named.lstrip("-").replace("-", "_")         # each is named by the part it leaves out
    assert sorted(outs) == sorted(parts)


def test_a_sweep_runs_here_skips_what_finished_and_resumes_what_stopped(tmp_path, capsys, monkeypatch):
    root = str(tmp_path / "runs")
    monkeypatch.setattr(sweep, "job_command", stand_in)
    dirs = [os.path.join(root, f"peg-ts-ptv-adaptive-e1-u2-w1-b8-buf240-s{s}") for s in (0, 1, 2)]
    for d, state in zip(dirs, ("done", "stopped")):           # s0 finished, s1 stopped: each a run of this plan
        os.makedirs(d)
        cfg = tacrl.parse_args([*TINY, "--seed", d[-1], "--run-dir", d])
        rundir.write_config(d, asdict(cfg))
        if state == "done":
            open(os.path.join(d, "eval.json"), "w").write("{}")
    assert cli.command("sweep", lambda: sweep.main(["--seeds", "0,1,2", "--root", root, "--list", "--", *TINY])) == 0
    assert capsys.readouterr().out.split() == ["done", dirs[0], "resume", dirs[1], "new", dirs[2]]
    assert cli.command("sweep", lambda: sweep.main(["--seeds", "0,1,2", "--root", root, "--", *TINY])) == 0
    out = capsys.readouterr().out
    assert "3 runs, 1 finished already; 2 to run here" in out and out.count("finished (") == 2
    assert [open(os.path.join(d, "train.log")).read().split() for d in dirs[1:]] == [["ep", "resume", "1"],
                                                                                    ["ep", "new", "1"]]
    argv = ["--seeds", "0", "--root", root, "--", *TINY, "--eval-levels", "2"]
    assert cli.command("sweep", lambda: sweep.main(argv)) == 2
    assert "eval_levels" in capsys.readouterr().err          # the setting that differs named; nothing overwritten


def test_progress_lines_from_runs_started_at_once_stay_whole():
    import threading
    import time
    out = []

    def log(m):                    # print's two writes (the line, then its newline), slowed so that threads meet
        out.append(m)
        time.sleep(0.05)
        out.append("\n")
    progress = sweep.Progress(4, log)
    jobs = [sweep.Job(f"runs/r{i}", [], "new") for i in range(4)]
    threads = [threading.Thread(target=progress.started, args=(j,)) for j in jobs]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted("".join(out).splitlines()) == [f"started runs/r{i} (new), its log runs/r{i}/train.log"
                                                 for i in range(4)]


def killed_once(marker, then="print('again')"):
    """A stand-in run that kills itself (SIGKILL) the first time, as a lost worker's run ends, then does `then`."""
    return [sys.executable, "-c", f"import os, signal\nif not os.path.exists({marker!r}):\n    open({marker!r}, 'w')"
            f"\n    os.kill(os.getpid(), signal.SIGKILL)\n{then}"]


def test_a_killed_run_is_resumed_by_the_sweep_and_a_run_that_cannot_write_is_not(tmp_path, monkeypatch):
    jobs = sweep.plan([], [0, 1, 2], str(tmp_path / "runs"), TINY)
    commands = {jobs[0].run_dir: killed_once(str(tmp_path / "m0")),                      # killed once: resumed
                jobs[1].run_dir: killed_once(str(tmp_path / "m1"), "raise SystemExit(74)"),  # then a full disk
                jobs[2].run_dir: killed_once(str(tmp_path / "m2"))}                      # killed, no retries left
    monkeypatch.setattr(sweep, "job_command", lambda job, threads: commands[job.run_dir])
    lines = []
    done = dict((j.run_dir, code) for j, code in sweep.run_local(jobs[:2], 2, 1, log=lines.append, retries=2))
    assert done == {jobs[0].run_dir: 0, jobs[1].run_dir: 74}
    assert open(os.path.join(jobs[0].run_dir, "train.log")).read().split() == ["again"]
    assert sum("killed by signal 9: resumed" in x for x in lines) == 2          # each once, the disk's not again
    assert any(jobs[1].run_dir in x and sweep.reason(74) in x for x in lines)
    (done, code), = sweep.run_local(jobs[2:], 1, 1, log=lines.append, retries=0)
    assert code == sweep.KILLED and "killed" in sweep.reason(code)
    # a retry of a run that had begun (its config.json written) resumes it, whatever flags its first try had
    import subprocess
    os.makedirs(jobs[0].run_dir, exist_ok=True)
    open(os.path.join(jobs[0].run_dir, "config.json"), "w").write("{}")
    seen = []
    monkeypatch.setattr(subprocess, "run", lambda cmd, **kw: seen.append(cmd) or subprocess.CompletedProcess(cmd, 0))
    assert sweep.run_job(REAL_COMMAND(jobs[0], 1), jobs[0].run_dir, {}, str(tmp_path)) == 0
    assert seen[0][1:] == [os.path.join(sweep.PROJECT, "tacrl.py"), "--resume", jobs[0].run_dir, "--threads", "1"]


@pytest.fixture(scope="module")
def ray_local():
    """A local Ray instance of 2 CPUs for this file's tests."""
    ray = pytest.importorskip("ray", reason="the `ray` extra is not installed")
    ray.init(num_cpus=2, include_dashboard=False, object_store_memory=100 * 2 ** 20, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_a_sweep_runs_as_ray_tasks_on_a_local_instance(tmp_path, monkeypatch, ray_local):
    """The plan's commands as Ray tasks, each writing its run dir's log where the driver runs (the same paths on
    every node); stand-in commands, as in the local test."""
    jobs = sweep.plan([], [0, 1], str(tmp_path / "runs"), TINY)
    monkeypatch.setattr(sweep, "job_command", lambda job, threads: [
        sys.executable, "-c", f"import os; print('run', {job.run_dir!r}, os.environ['OMP_NUM_THREADS'], os.getcwd())"])
    monkeypatch.chdir(tmp_path)
    lines = []
    done = sweep.run_ray(jobs, "local", 1, log=lines.append)
    assert [code for _, code in done] == [0, 0] and sum("finished (" in x for x in lines) == 2
    for j in jobs:
        assert open(os.path.join(j.run_dir, "train.log")).read().split() == ["run", j.run_dir, "1", str(tmp_path)]


def test_a_run_killed_on_ray_is_retried_and_resumes_from_its_checkpoint(tmp_path, monkeypatch, ray_local):
    """A run's process killed (SIGKILL) after it began: Ray's retry runs the same run dir with --resume. A stand-in
    tacrl.py begins as a run does (its config.json) and is killed the first time; test_train checks that a resumed
    run is the same as one never stopped."""
    fake = tmp_path / "tacrl.py"
    fake.write_text("import os, signal, sys\nrun_dir = sys.argv[sys.argv.index('--run-dir') + 1] if '--run-dir' in "
                    "sys.argv else None\nif run_dir:\n    open(os.path.join(run_dir, 'config.json'), 'w').write('{}')"
                    "\n    os.kill(os.getpid(), signal.SIGKILL)\nprint(*sys.argv[1:])\n")
    jobs = sweep.plan([], [0], str(tmp_path / "runs"), TINY)
    run_dir = jobs[0].run_dir
    monkeypatch.setattr(sweep, "job_command", lambda job, threads: [sys.executable, str(fake),
                                                                     *REAL_COMMAND(job, threads)[2:]])
    lines = []
    (job, code), = sweep.run_ray(jobs, "local", 1, log=lines.append, retries=2)
    assert code == 0
    assert open(os.path.join(run_dir, rundir.LOG)).read().split() == ["--resume", run_dir, "--threads", "1"]


@pytest.mark.parametrize("argv, names", [     # what the one line names: the flag, or the experiment at fault
    (["nothing"], "'nothing'"),
    ([], "--"),
    (["table1", "--", "--task", "gear"], "--"),
    (["--", "--task", "peg", "--seed", "3"], "--seed"),
    (["--seeds", "0,0", "--", "--task", "peg"], "--seeds"),
    (["--", "--task", "peg", "--lr", "2"], "--lr"),
    (["--threads", "0", "--", "--task", "peg"], "--threads"),
    (["--threads", "3", "--", "--task", "peg"], "--threads"),              # an update has two halves
    (["--seeds", "2,-3", "--", "--task", "peg"], "-3"),                    # every seed checked first
])
def test_sweep_mistakes_are_one_line_and_exit_2(argv, names, capsys, tmp_path):
    assert cli.command("sweep", lambda: sweep.main(["--root", str(tmp_path), *argv])) == 2
    err = capsys.readouterr().err
    assert err.startswith("sweep: error:") and names in err and err.count("\n") == 1
    assert not os.listdir(tmp_path)


def test_failed_runs_are_named_and_the_sweep_exits_1(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sweep, "job_command", lambda job, threads: ["python3", "-c", "import sys; sys.exit(3)"])
    assert cli.command("sweep", lambda: sweep.main(["--seeds", "0,1", "--root", str(tmp_path), "--", *TINY])) == 1
    err = capsys.readouterr().err
    assert err.startswith("sweep: failed:") and err.count("\n") == 1 and all(d in err for d in ("s0", "s1"))


def test_runs_never_ask_for_more_threads_than_cores_and_a_warning_says_where_the_user_does(tmp_path, capsys,
                                                                                           monkeypatch):
    monkeypatch.setattr(sweep.os, "cpu_count", lambda: 2)
    argv = ["--seeds", "0,1,2", "--root", str(tmp_path), "--dry-run"]
    assert cli.command("sweep", lambda: sweep.main([*argv, "--", *TINY])) == 0
    out, err = capsys.readouterr()
    assert err == "" and out.count("--threads 1") == 3
    assert cli.command("sweep", lambda: sweep.main([*argv, "--threads", "2", "--parallel", "2", "--", *TINY])) == 0
    err = capsys.readouterr().err
    assert err.startswith("sweep: warning:") and "--threads 1" in err
