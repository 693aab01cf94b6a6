"""The two-step baseline's parts (hole detection, calibration and visual servo)."""

import dataclasses

import numpy as np

import baselines
import command
import sim
import tacrl


def test_hole_blob_finds_the_hole_and_nothing_in_a_blank_image():
    env = sim.AssemblyEnv("peg", e_r=0.02)
    obs, _ = env.reset(options={"error": np.zeros(4)})
    u, v, r = sim.hole_blob(obs["image"][0])
    obs2, _ = env.reset(options={"error": np.array([0.005, 0, 0, 0])})
    u2, v2, _ = sim.hole_blob(obs2["image"][0])
    env.close()
    assert abs(u - 40) < 3 and 4 < r < 20           # centred left-right, a hole-sized disc
    assert abs(v2 - v) > 3                           # 5 mm of error moves it several pixels
    assert sim.hole_blob(np.full((80, 80), 200, np.uint8)) is None


def test_keypoint_rl_sees_the_hole_as_a_keypoint_and_only_in_the_peg_env_that_asks():
    with sim.AssemblyEnv("peg", e_r=0.02, keypoint=True) as env:
        obs, _ = env.reset(seed=4)
        u, v, r = sim.hole_blob(obs["image"][0])
        kp = obs["keypoint"]
        assert kp.dtype == np.float32 and kp[3] == 1.0 and np.allclose(kp[:3], [u / 80 - 0.5, v / 80 - 0.5, r / 80])
        assert env.observation_space["keypoint"].contains(kp)
    assert not sim.hole_keypoint(np.full((80, 80), 200, np.uint8)).any()       # no hole in view: zeros
    with sim.AssemblyEnv("peg", e_r=0.02) as env:
        assert "keypoint" not in env.reset(seed=4)[0]
    assert tacrl.main(["--task", "gear", "--obs", "ts-ptk"]) == 2               # the gear's shaft is no such keypoint


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


def test_ablation_runs_get_run_dirs_of_their_own():
    dirs = [tacrl.parse_args(argv).run_dir for argv in (
        [], ["--roi", "full"], ["--curriculum", "none", "--error-mm", "10"], ["--curriculum", "none"],
        ["--curriculum", "none", "--error-mm", "30", "--roi", "200", "--seed", "1"],
        ["--obs", "v", "--critic", "multimodal"])]
    assert dirs == ["runs/peg-ts-ptv-adaptive-s0", "runs/peg-ts-ptv-adaptive-roi-full-s0",
                    "runs/peg-ts-ptv-none-e10-s0", "runs/peg-ts-ptv-none-s0", "runs/peg-ts-ptv-none-e30-roi-200-s1",
                    "runs/peg-v-adaptive-multimodal-s0"]


def test_every_training_choice_is_in_the_run_dir_name():
    """One flag changed from its default gives a run dir of its own: no learned run's name is another's."""
    dirs = {"default": command.default_run_dir(tacrl.Config())}
    for f in dataclasses.fields(tacrl.Config):
        if f.name in command.NOT_LEARNING:
            continue
        cfg, meta = tacrl.Config(), f.metadata
        if f.name == "randomize":
            value = "light,parts"
        elif meta["choices"]:
            value = next(c for c in meta["choices"] if c != f.default)
        elif isinstance(f.default, bool):
            value = not f.default
        else:
            hi = (meta["bounds"] or (None, None))[1]
            value = f.type(f.default + 1) if hi is None or f.default + 1 < hi else (f.default + hi) / 2
        setattr(cfg, f.name, value)
        dirs[f.name] = command.default_run_dir(cfg)
    assert len(set(dirs.values())) == len(dirs), dirs
