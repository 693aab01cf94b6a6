"""tacrl.py through subprocess: bad input gives one line and exit code 2; a tiny run writes its JSON."""
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
                                  ["--video", "out.avi"]])
def test_bad_arguments_exit_2_with_one_line(args):
    r = run(*args)
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
