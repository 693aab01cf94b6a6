"""The two-step baseline's parts (hole detection, calibration and visual servo), and the command lines
of tools/seeds.py."""
import os

import numpy as np
import pytest

import baselines
import seeds
import sim
import tacrl


def test_hole_blob_finds_the_hole_and_nothing_in_a_blank_image():
    env = sim.AssemblyEnv("peg", e_r=0.02)
    obs, _ = env.reset(options={"error": np.zeros(4)})
    u, v, r = baselines.hole_blob(obs["image"])
    obs2, _ = env.reset(options={"error": np.array([0.005, 0, 0, 0])})
    u2, v2, _ = baselines.hole_blob(obs2["image"])
    env.close()
    assert abs(u - 40) < 3 and 4 < r < 20           # centred left-right, a hole-sized disc
    assert abs(v2 - v) > 3                           # 5 mm of error moves it several pixels
    assert baselines.hole_blob(np.full((80, 80), 200, np.uint8)) is None


def test_two_step_servo_removes_most_of_a_10_mm_error():
    env = sim.AssemblyEnv("peg", e_r=0.02)
    ts = baselines.TwoStep(env)
    assert ts.calibrate(episodes=12) < 0.004         # median lateral error of the fit, m
    obs, info = env.reset(options={"error": np.array([0.010, -0.008, 0.0, 0.0])})
    ts.reset()
    for _ in range(ts.SERVO + 4):
        obs, _, _, _, info = env.step(ts(obs))
    env.close()
    assert ts.phase == "descend"
    assert np.linalg.norm(info["goal_offset"][:2]) < 0.4 * np.hypot(0.010, 0.008)


def test_two_step_calibration_is_the_same_in_every_process_and_after_any_history():
    # its episodes' sensor and image noise come from seeds of its own, not the env's unseeded
    # generator: the same --eval two-step gave 0.60-0.75 at 20 mm from one process to the next
    fits = []
    for history in (False, True):
        env = sim.AssemblyEnv("peg", e_r=0.02)
        if history:
            env.reset()
            env.step(np.ones(6))
        ts = baselines.TwoStep(env)
        ts.calibrate(episodes=4)
        env.close()
        fits.append((ts.coef, ts.bias))
    assert np.array_equal(fits[0][0], fits[1][0]) and np.array_equal(fits[0][1], fits[1][1])


def test_seed_commands_one_run_dir_and_thread_share_per_seed():
    argv = ["--task", "gear", "--train-episodes", "5", "--seed", "7"]
    parallel, jobs = seeds.seed_commands([0, 1, 2], argv, cores=2)
    assert parallel == 2 and [j[0] for j in jobs] == [0, 1, 2]
    assert [j[1] for j in jobs] == [f"runs/gear-ts-ptv-adaptive-s{s}" for s in (0, 1, 2)]
    cmd = jobs[1][2]
    assert cmd.count("--seed") == 1 and cmd[cmd.index("--seed") + 1] == "1" and cmd[cmd.index("--threads") + 1] == "1"
    assert cmd[cmd.index("--train-episodes") + 1] == "5" and cmd[cmd.index("--task") + 1] == "gear"


def test_seeds_never_ask_for_more_threads_than_cores_and_warn_where_the_user_does(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    parallel, jobs = seeds.seed_commands([0, 1, 2], ["--task", "peg"], cores=2)   # 2 at a time, 1 thread each
    assert parallel * int(jobs[0][2][jobs[0][2].index("--threads") + 1]) <= 2 and capsys.readouterr().err == ""
    seeds.seed_commands([0, 1], ["--task", "peg", "--threads", "2"], cores=2)
    assert capsys.readouterr().err.startswith("seeds: warning: 2 x 2 torch threads on 2 cores")
    tacrl.parse_args(["--task", "peg", "--threads", str(2 * (os.cpu_count() or 1))])
    assert "tacrl: warning:" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [[], ["--task", "peg"], ["0,x"], ["1,1"], ["0,1", "--task", "screw"],
                                  ["0,1", "--eval", "initial"]])
def test_seeds_mistakes_are_one_line_and_exit_2(argv, capsys):
    assert tacrl.command("seeds", lambda: seeds.main(argv)) == 2
    err = capsys.readouterr().err
    assert err.startswith("seeds: error:") and err.count("\n") == 1


def test_ablation_runs_get_run_dirs_of_their_own():
    dirs = [tacrl.parse_args(argv).run_dir for argv in (
        [], ["--roi", "full"], ["--curriculum", "none", "--error-mm", "10"], ["--curriculum", "none"],
        ["--curriculum", "none", "--error-mm", "30", "--roi", "200", "--seed", "1"], ["--obs", "v", "--critic", "multimodal"])]
    assert dirs == ["runs/peg-ts-ptv-adaptive-s0", "runs/peg-ts-ptv-adaptive-roi-full-s0",
                    "runs/peg-ts-ptv-none-e10-s0", "runs/peg-ts-ptv-none-s0", "runs/peg-ts-ptv-none-e30-roi-200-s1",
                    "runs/peg-v-adaptive-multimodal-s0"]
