"""tacrl.py's command line: every flag described once, a user's mistake is one line and exit code 2,
the hand-designed policy's evaluation row, a corrupt checkpoint or policy file is a one-line error."""
import dataclasses
import json
import os
import subprocess
import sys

import pytest

import tacrl

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.parametrize("args", [["--task", "screw"], ["--error-mm", "-3"], ["--episodes", "0"],
                                  ["--context", "moon"], ["--bogus"], ["--episodes", "many"],
                                  ["--video", "out.avi"], ["--obs", "smell"], ["--curriculum", "fast"],
                                  ["--eval", "no/such/policy.pt"], ["--resume", "no/such/run"],
                                  ["--eval-levels", "5,x"], ["--device", "tpu"], ["--threads", "-1"],
                                  ["--eval", "two-step", "--task", "gear"], ["--critic", "oracle"],
                                  ["--lr", "0"], ["--gamma", "1"], ["--clearance-mm", "3"],
                                  ["--train-episode", "5"],           # a typo: no flag is taken for another
                                  ["--seeds", "0,1"]])                # seeds.py's now
def test_bad_arguments_exit_2_with_one_line(args, capsys):
    assert tacrl.main(args) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and err.startswith("tacrl: error:")


def test_bad_argument_through_the_shell():
    r = subprocess.run([sys.executable, os.path.join(ROOT, "tacrl.py"), "--task", "screw"], capture_output=True,
                       text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and r.stderr.startswith("tacrl: error:")
    assert "Traceback" not in r.stderr


def test_each_flag_is_described_once_in_help(capsys):
    with pytest.raises(SystemExit):
        tacrl.parse_args(["--help"])
    text = "".join(capsys.readouterr().out.split())          # argparse wraps lines, also at hyphens
    for f in dataclasses.fields(tacrl.Config):
        flag = "--" + f.name.replace("_", "-")
        assert flag in text and "".join(f.metadata["help"].split()) in text, flag


def test_initial_policy_row_and_json(tmp_path, capsys):
    out = tmp_path / "row.json"
    assert tacrl.main(["--task", "peg", "--eval", "initial", "--error-mm", "0", "--episodes", "1", "--json", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "SR" in stdout and "initial peg 0mm" in stdout
    row = json.loads(out.read_text())
    assert row["success_rate"] == 1.0 and row["episodes"] == 1
    assert 5.0 < row["completion_time_s"][0] < 24.0
    assert row["cumulative_reward"][0] > 0


def test_corrupt_checkpoint_is_a_one_line_error(tmp_path, capsys):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "config.json").write_text(json.dumps({"task": "peg"}))
    (run_dir / "ckpt.pt").write_bytes(b"not a checkpoint")
    assert tacrl.main(["--resume", str(run_dir)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "ckpt.pt is damaged" in err


def test_corrupt_policy_is_a_one_line_error(tmp_path, capsys):
    bad = tmp_path / "policy.pt"
    bad.write_bytes(b"\x80\x02garbage")
    assert tacrl.main(["--eval", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot load" in err
