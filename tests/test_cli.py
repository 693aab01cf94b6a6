"""tacrl.py's command line: every flag described once, a user's mistake is one line and exit code 2,
the hand-designed policy's evaluation row, a corrupt checkpoint or policy file is a one-line error."""
import csv
import dataclasses
import json
import os
import subprocess
import sys

import cv2
import evaluate
import pytest

import scene
import tacrl

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.parametrize("args", [["--task", "screw"], ["--episodes", "many"], ["--video", "out.avi"],
                                  ["--eval", "no/such/policy.pt"], ["--resume", "no/such/run"],
                                  ["--seeds", "0,1"]])                # tools/sweep.py's now
def test_bad_arguments_exit_2_with_one_line(args, capsys):
    assert tacrl.main(args) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and err.startswith("tacrl: error:")


def test_the_readmes_command_through_the_shell_in_a_tiny_configuration_without_the_extras(tmp_path):
    # `python tacrl.py --task peg` as the quickstart runs it, with a budget of seconds, where neither gymnasium
    # nor tensorboard can be imported (the optional extras): the default run dir, a progress line an episode
    # with its ETA, the finished run's files
    (tmp_path / "hidden").mkdir()
    for extra in ("gymnasium", "tensorboard"):
        (tmp_path / "hidden" / f"{extra}.py").write_text(f"raise ImportError('{extra} is not installed')\n")
    steps = 9           # an episode's, not 120, as the in-process tests' (Python runs sitecustomize before the command)
    (tmp_path / "hidden" / "sitecustomize.py").write_text(f"import sys\nsys.path.insert(0, {ROOT!r})\n"
                                                          f"import sim\nsim.MAX_STEPS = {steps}\n")
    tiny = ["--train-episodes", "1", "--warmup", "0", "--updates", "2", "--batch", "8", "--buffer", "240",
            "--episodes", "1", "--eval-levels", "0"]
    shell = lambda *argv: subprocess.run([sys.executable, os.path.join(ROOT, "tacrl.py"), *argv],  # noqa: E731
                                         capture_output=True,
                                         text=True, cwd=tmp_path, timeout=300,
                                         env={**os.environ, "PYTHONPATH": str(tmp_path / "hidden")})
    r = shell("--task", "peg", *tiny)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert len([x for x in r.stdout.splitlines() if x.startswith("ep ") and " ETA " in x]) == 1
    run = tmp_path / "runs" / "peg-ts-ptv-adaptive-u2-w0-b8-buf240-s0"     # the default name, with what tiny changed
    assert sorted(os.listdir(run)) == ["ckpt.pt", "config.json", "curves.png", "eval.json", "metrics.csv", "policy.pt",
                                       "replay"]
    assert json.loads((run / "eval.json").read_text())["train_episodes"] == 1
    with open(run / "metrics.csv") as f:
        assert [int(row["steps"]) for row in csv.DictReader(f)] == [steps]    # the budget above was the one run


def test_each_flag_is_described_once_in_help(capsys):
    with pytest.raises(SystemExit):
        tacrl.parse_args(["--help"])
    text = "".join(capsys.readouterr().out.split())          # argparse wraps lines, also at hyphens
    for f in dataclasses.fields(tacrl.Config):
        flag = "--" + f.name.replace("_", "-")
        assert flag in text and "".join(f.metadata["help"].split()) in text, flag


def test_help_lists_each_flag_under_its_group(capsys):
    with pytest.raises(SystemExit):
        tacrl.parse_args(["--help"])
    lines = capsys.readouterr().out.split("\n")
    heads = {title: lines.index(title + ":") for title in tacrl.Config.GROUPS}      # each title a heading
    assert list(heads.values()) == sorted(heads.values())
    ends = dict(zip(heads, list(heads.values())[1:] + [len(lines)]))
    for title, names in tacrl.Config.GROUPS.items():
        section = [x.split()[0] for x in lines[heads[title] + 1:ends[title]] if x.startswith("  --")]
        assert section == ["--" + n.replace("_", "-") for n in names], title


def test_a_module_another_package_shadows_is_one_line_naming_it(tmp_path):
    # python-control's `control` (or Hugging Face's `evaluate`) installed before ours on the path
    (tmp_path / "control").mkdir()
    (tmp_path / "control" / "__init__.py").write_text("")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), ROOT])}
    for argv in (["-c", "import sim"], ["-m", "tacrl", "--task", "peg"]):
        p = subprocess.run([sys.executable, *argv], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60)
        last = p.stderr.strip().split("\n")[-1]
        assert p.returncode != 0 and "control" in last and str(tmp_path / "control") in last, p.stderr
        assert argv[0] == "-c" or p.stderr.count("\n") == 1           # the command: that line alone


def test_initial_policy_row_json_and_a_video_browsers_play(tmp_path, capsys, monkeypatch):
    out, video = tmp_path / "row.json", tmp_path / "ep.webm"
    monkeypatch.setattr(scene, "VIDEO_W", 64)             # small frames: at 640 x 480, their renders and their
    monkeypatch.setattr(scene, "VIDEO_H", 48)             # encoding would take most of the test's time
    assert tacrl.main(["--task", "peg", "--eval", "initial", "--error-mm", "0", "--episodes", "1", "--json", str(out),
                       "--video", str(video)]) == 0
    stdout = capsys.readouterr().out
    assert "SR" in stdout and "initial peg 0mm" in stdout
    row = json.loads(out.read_text())
    assert row["success_rate"] == 1.0 and row["episodes"] == 1
    assert 5.0 < row["completion_time_s"][0] < 24.0
    assert row["cumulative_reward"][0] > 0
    # WebM (its EBML header and doctype) holding VP9, a frame a policy step of the view's size, as OpenCV reads it back
    head = video.read_bytes()[:64]
    assert head.startswith(b"\x1a\x45\xdf\xa3") and b"webm" in head
    cap = cv2.VideoCapture(str(video))
    fourcc = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little")
    size = (cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    cap_fps, frames = cap.get(cv2.CAP_PROP_FPS), 0
    while cap.read()[0]:
        frames += 1
    cap.release()
    assert fourcc == b"VP90" and size == (64, 48) and evaluate.VIDEO_FPS >= 20
    assert frames == round(row["completion_time_s"][0] * evaluate.VIDEO_FPS)        # the simulation's own time
    assert cap_fps == evaluate.VIDEO_FPS


def test_a_video_format_this_opencv_cannot_write_is_one_line_before_any_work(tmp_path, capsys):
    # OpenCV's pip wheels have no H.264 encoder; one that has writes the .mp4, and then this checks nothing
    ok = tacrl.main(["--eval", "initial", "--episodes", "1", "--error-mm", "0", "--video", str(tmp_path / "ep.mp4")])
    err = capsys.readouterr().err
    assert (ok == 0 and (tmp_path / "ep.mp4").stat().st_size > 0) or \
        (ok == 2 and err.count("\n") == 1 and ".webm" in err and not os.listdir(tmp_path))
