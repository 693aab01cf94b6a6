"""tacrl.py: bad input gives one line and exit code 2; the initial policy's row; a tiny training run
writes every file, survives an interrupt and resumes; a saved policy evaluates; a corrupt
checkpoint or policy file is a one-line error."""
import csv
import json
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(*args):
    return subprocess.run([sys.executable, os.path.join(ROOT, "tacrl.py"), *args], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)


@pytest.mark.parametrize("args", [["--task", "screw"], ["--error-mm", "-3"], ["--episodes", "0"],
                                  ["--context", "moon"], ["--bogus"], ["--episodes", "many"],
                                  ["--video", "out.avi"], ["--obs", "smell"], ["--curriculum", "fast"],
                                  ["--eval", "no/such/policy.pt"], ["--resume", "no/such/run"],
                                  ["--eval-levels", "5,x"], ["--device", "tpu"], ["--threads", "-1"],
                                  ["--eval", "two-step", "--task", "gear"], ["--seeds", "0,x"], ["--seeds", "1,1"],
                                  ["--aux-weight", "-1"], ["--report", "no/such/run*"], ["--critic", "oracle"],
                                  ["--archive", "no/such/run*"],
                                  ["--aux-weight", "1"]])          # aux needs --critic multimodal
def test_bad_arguments_exit_2_with_one_line(args, capsys):
    import tacrl
    assert tacrl.main(args) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and err.startswith("tacrl: error:")


def test_bad_argument_through_the_shell():
    r = run("--task", "screw")
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and r.stderr.startswith("tacrl: error:")
    assert "Traceback" not in r.stderr


def test_initial_policy_row_and_json(tmp_path):
    out = tmp_path / "row.json"
    r = run("--task", "peg", "--eval", "initial", "--error-mm", "0", "--episodes", "1", "--json", str(out))
    assert r.returncode == 0, r.stderr
    assert "SR" in r.stdout and "initial peg 0mm" in r.stdout
    row = json.loads(out.read_text())
    assert row["success_rate"] == 1.0 and row["episodes"] == 1
    assert 5.0 < row["completion_time_s"][0] < 24.0
    assert row["cumulative_reward"][0] > 0


TINY = ["--task", "peg", "--error-mm", "1", "--train-episodes", "3", "--warmup", "1", "--updates", "2",
        "--batch", "8", "--episodes", "1", "--eval-levels", "1", "--buffer", "40"]


def test_training_writes_every_file_resumes_and_evaluates(tmp_path, capsys, monkeypatch):
    import sim
    import tacrl
    # episodes of at most 30 steps, not 120: the untrained policy runs every one to the limit, and this
    # test is about files, resuming and evaluating, not about inserting
    monkeypatch.setattr(sim, "MAX_STEPS", 30)
    run_dir = str(tmp_path / "run")
    lines = []

    def interrupt_after_episode_2(msg):
        lines.append(msg)
        if msg.startswith("ep    2/3"):
            raise KeyboardInterrupt      # as Ctrl-C right after episode 2 was saved
    a = tacrl.parse_args(TINY + ["--run-dir", run_dir])
    with pytest.raises(KeyboardInterrupt):
        tacrl.train(a, log=interrupt_after_episode_2)
    assert sorted(os.listdir(os.path.join(run_dir, "replay"))) == ["ep_000001.npz", "ep_000002.npz"]
    # starting over in the same directory is refused; --resume continues at episode 3 (in-process: a
    # subprocess costs seconds of imports, and test_bad_argument_through_the_shell covers the shell)
    capsys.readouterr()
    assert tacrl.main(TINY + ["--run-dir", run_dir]) == 2
    assert "--resume" in capsys.readouterr().err
    assert tacrl.main(["--resume", run_dir]) == 0
    out = capsys.readouterr().out
    assert "resumed" in out and "ep    3/3" in out and "ep    1/3" not in out
    for f in ("config.json", "ckpt.pt", "metrics.csv", "policy.pt", "curves.png", "eval.json"):
        assert os.path.getsize(os.path.join(run_dir, f)) > 0, f
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        rows = list(csv.DictReader(f))
    assert [int(x["episode"]) for x in rows] == [1, 2, 3]
    assert int(rows[2]["updates"]) == 2 and int(rows[0]["updates"]) == 0     # none during warm-up
    # on disk: the newest episodes that fill the 40-transition buffer, no older ones
    steps = [int(x["steps"]) for x in rows]
    keep = next(i for i in range(3, -1, -1) if sum(steps[i:]) >= 40 or i == 0)
    kept = sorted(os.listdir(os.path.join(run_dir, "replay")))
    assert kept == [f"ep_{i + 1:06d}.npz" for i in range(keep, 3)], (steps, kept)
    ev = json.loads(open(os.path.join(run_dir, "eval.json")).read())
    assert [row["error_mm"] for row in ev["rows"]] == [1.0] and ev["eval_seed"] != ev["seed"] and ev["simulator"] == "new"
    # --eval of policy.pt in a fresh process repeats eval.json to the last digit: training evaluates in a
    # fresh simulator, not in the one it trained in (PyBullet carries state from episode to episode)
    pol = os.path.join(run_dir, "policy.pt")
    again = tmp_path / "again.json"
    assert tacrl.main(["--task", "peg", "--eval", pol, "--error-mm", "1", "--episodes", "1", "--json", str(again)]) == 0
    keys = ("success_rate", "cumulative_reward", "contact_force_x_N", "contact_force_y_N", "contact_force_z_N")
    assert {k: ev["rows"][0][k] for k in keys} == {k: json.loads(again.read_text())[k] for k in keys}
    # the saved policy keeps the exploration range it was trained with (Ex_r 2 mm, the floor, here) ...
    import torch
    d = torch.load(pol, weights_only=True)
    assert ev["rows"][0]["ex_r_mm"] == round(max(d["ex_r"], 0.002) * 1000, 3) == 2.0
    assert d["e_r_max"] == 0.02              # and the env it saw: ROI and X_i for 20 mm, the least there is
    # ... and evaluates like the initial one, at any E_r with that Ex_r (set to 15 mm here to tell them apart)
    d["ex_r"] = 0.015
    torch.save(d, pol)
    out = tmp_path / "row.json"
    assert tacrl.main(["--task", "peg", "--eval", pol, "--error-mm", "0", "--episodes", "1", "--json", str(out)]) == 0
    assert "TA-MRP peg 0mm" in capsys.readouterr().out
    row = json.loads(out.read_text())
    assert row["episodes"] == 1 and row["error_mm"] == 0 and row["ex_r_mm"] == 15.0
    # ... but not for the other task
    assert tacrl.main(["--task", "gear", "--eval", os.path.join(run_dir, "policy.pt")]) == 2
    assert "trained for --task peg" in capsys.readouterr().err
    # ... nor in another view than it learned (a silent default would evaluate the wrong images)
    assert tacrl.main(["--task", "peg", "--eval", pol, "--roi", "200"]) == 2
    assert "trained with --roi task, not 200" in capsys.readouterr().err
    # --archive keeps what the report reads, not the checkpoint or the replay, and skips a run that has
    # not finished (no eval.json)
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    for f in ("config.json", "metrics.csv"):
        (unfinished / f).write_text(open(os.path.join(run_dir, f)).read())
    results = tmp_path / "results"
    assert tacrl.archive_runs(f"{run_dir},{unfinished}", dest=str(results), log=lines.append) == [str(results / "run")]
    assert sorted(os.listdir(results / "run")) == ["config.json", "curves.png", "eval.json", "metrics.csv", "policy.pt"]
    assert any(str(unfinished) in x and "not finished" in x for x in lines)
    assert tacrl.main(["--archive", str(unfinished)]) == 2
    # the report, from the archive alone, lists the run and draws its curves (the two-step row comes
    # from its cache file here: evaluating the baseline takes a minute)
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "two-step-peg-20mm.json").write_text(out.read_text())
    (docs / "fig-peg-obs.png").write_bytes(b"an earlier report's figure, of runs this one has not got")
    assert tacrl.main(["--report", str(results / "*"), "--report-dir", str(docs)]) == 0
    text = (docs / "RESULTS.md").read_text()
    assert str(results / "run") in text and "Table 1" in text and "Table 2" in text
    assert "1.00 (at 1 mm)" in text or "0.00 (at 1 mm)" in text    # its levels are named: not the usual 5/10/15/20
    assert (docs / "fig-peg-runs.png").stat().st_size > 0 and not (docs / "fig-peg-obs.png").exists()
    # Fig. 16, which the report draws for our method's first peg run (the tiny run is not one)
    tacrl.behaviour_plot(tacrl.load_run(run_dir), str(docs / "behaviour.png"), error_mm=0.0)
    assert (docs / "behaviour.png").stat().st_size > 0
    tacrl.plot_views("peg", ("full",), str(docs / "views.png"))     # the images beside Fig. 12's bars
    assert (docs / "views.png").stat().st_size > 0


def test_corrupt_checkpoint_and_policy_are_one_line_errors(tmp_path, capsys):
    import tacrl
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "config.json").write_text(json.dumps({"task": "peg"}))
    (run_dir / "ckpt.pt").write_bytes(b"not a checkpoint")
    assert tacrl.main(["--resume", str(run_dir)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "corrupt" in err
    bad = tmp_path / "policy.pt"
    bad.write_bytes(b"\x80\x02garbage")
    assert tacrl.main(["--eval", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot load" in err


@pytest.mark.parametrize("changes, expected", [
    ({}, {"methods": "ours", "roi": "task attention (Eq. 11)", "curriculum": "curriculum adaptive, 20 mm"}),
    ({"vanilla": True}, {"methods": "vanilla"}),
    ({"obs": "v"}, {"methods": "visual"}),
    ({"obs": "v", "critic": "multimodal"}, {"methods": "visual (critic multimodal)"}),   # the paper's critics
    ({"obs": "pt", "curriculum": "ex10"}, {"obs": "P-T"}),
    ({"curriculum": "ex10"}, {"obs": "Time-series P-T-V"}),
    ({"curriculum": "none", "error_mm": 10.0}, {"curriculum": "no curriculum, 10 mm"}),
    ({"curriculum": "g2-c10", "error_mm": 30.0}, {"curriculum": "curriculum g2-c10, 30 mm"}),
    ({"error_mm": 30.0}, {"curriculum": "curriculum adaptive, 30 mm"}),
    ({"roi": "full"}, {"roi": "ROI full"}),
    ({"curriculum": "g2-c10"}, {}),                       # at 20 mm: none of the paper's comparisons
    ({"lr": 1e-3}, {}),                                   # another learning setting: compared with nothing
])
def test_report_families(changes, expected):
    """Which of the paper's comparisons (Table 1, Fig. 9, 10, 11) a run's curves join in the report."""
    import dataclasses
    import tacrl
    cfg = {**dataclasses.asdict(tacrl.Args()), **changes}
    assert tacrl.families(cfg) == expected


def test_report_command_of_a_run():
    """The runs table gives each run the command that reproduces it: the flags off their defaults."""
    import dataclasses
    import tacrl
    cfg = {**dataclasses.asdict(tacrl.Args()), "vanilla": True, "error_mm": 30.0, "seed": 2, "threads": 1,
           "run_dir": "runs/x"}
    assert tacrl.command_of(cfg) == "python tacrl.py --task peg --error-mm 30 --seed 2 --vanilla"
    assert tacrl.parse_args(tacrl.command_of(cfg).split()[2:]).vanilla
