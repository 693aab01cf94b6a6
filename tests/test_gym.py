"""sim.AssemblyEnv as a Gymnasium env (the optional extra `.[gym]`, which CI installs): registration,
gymnasium's own env checker on both tasks, render(), vector envs. (The project without gymnasium:
tests/test_cli.py runs the README's command so.)"""
import os
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import evaluate
import scene
import sim  # noqa: F401  (importing sim registers the envs)
import tacrl

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.parametrize("env_id", ["tacrl/PegInsertion-v0", "tacrl/GearInsertion-v0"])
def test_gymnasium_env_checker_passes_without_a_warning(env_id):
    env = gym.make(env_id)
    assert env.unwrapped.e_r == sim.E_R_FINAL            # the paper's task: errors up to 20 mm
    with warnings.catch_warnings():
        warnings.simplefilter("error")                   # the checker's warnings fail the test too
        check_env(env.unwrapped)
    env.close()


def test_the_image_space_is_what_image_libraries_take_for_an_image():
    # Stable-Baselines3's is_image_space and its env checker's test: a uint8 Box of 3 axes, bounds 0 and 255,
    # channels (1, 3 or 4) on the first or last axis; then a user's CNN policy reads it with no wrapper
    space = gym.make("tacrl/PegInsertion-v0").observation_space["image"]
    obs, _ = gym.make("tacrl/PegInsertion-v0").reset(seed=0)
    assert isinstance(space, gym.spaces.Box) and space.dtype == np.uint8 and space.shape == (1, sim.IMG, sim.IMG)
    assert (space.low == 0).all() and (space.high == 255).all() and space.contains(obs["image"])


def test_registered_env_steps_through_gymnasium_wrappers_and_renders():
    env = gym.wrappers.FlattenObservation(gym.make("tacrl/PegInsertion-v0", render_mode="rgb_array"))
    obs, info = env.reset(seed=0)
    assert obs.shape == (80 * 80 + 2 * 32 * 6,) and "goal_offset" in info
    obs, r, term, trunc, info = env.step(env.action_space.sample())
    assert isinstance(r, float) and not term and not trunc
    frame = env.render()
    assert frame.shape == (scene.VIDEO_H, scene.VIDEO_W, 3) and frame.dtype == np.uint8 and frame.std() > 5
    env.close()
    env.close()                                          # closing twice is allowed


def test_async_vector_env_gives_what_single_envs_give_on_the_same_seeds():
    # Gymnasium's way to collect from several envs at once: each in a process of its own, started by
    # 'spawn' (a fork of a process that has run torch can hang), each building its own PyBullet world
    envs = gym.make_vec("tacrl/PegInsertion-v0", num_envs=2, vectorization_mode="async",
                        vector_kwargs={"context": "spawn"})
    actions = np.random.default_rng(0).uniform(-1, 1, (3, 2, 6)).astype(np.float32)
    obs, _ = envs.reset(seed=[5, 9])
    assert not np.array_equal(obs["pose_hist"][0], obs["pose_hist"][1])     # two envs, two seeds' errors
    got = [(obs, None)]
    for a in actions:
        obs, r, term, trunc, _ = envs.step(a)
        assert not term.any() and not trunc.any()
        got.append((obs, r))
    envs.close()
    for i, seed in enumerate((5, 9)):
        env = gym.make("tacrl/PegInsertion-v0")
        want = [(env.reset(seed=seed)[0], None)] + [env.step(a[i])[:2] for a in actions]
        env.close()
        for (o_vec, r_vec), (o, r) in zip(got, want):
            assert r is None or r_vec[i] == r
            for k in o:
                assert np.array_equal(o_vec[k][i], o[k]), (seed, k)


def test_a_saved_policy_drives_the_registered_env_as_it_was_trained(tmp_path):
    # the README's use from Python: tacrl.load_policy, the env made with evaluate.env_kwargs, one observation or a
    # vector env's batch of them (the batch as gymnasium stacks it)
    sac = tacrl.make_sac(tacrl.parse_args(["--task", "peg", "--threads", "1", "--roi", "full"]))
    meta = {"task": "peg", "obs": "ts-ptv", "roi": "full", "vanilla": False, "ex_r": 0.004, "e_r_max": 0.02}
    evaluate.save_policy(str(tmp_path / "policy.pt"), sac, meta)
    pi = tacrl.load_policy(str(tmp_path / "policy.pt"))
    env = gym.make("tacrl/PegInsertion-v0", **evaluate.env_kwargs(pi))
    assert (env.unwrapped.roi_name, env.unwrapped.ex_r) == ("full", 0.004)        # the view and Ex_r it trained with
    obs = [env.reset(seed=s)[0] for s in (0, 1)]
    batch = {k: np.stack([o[k] for o in obs]) for k in obs[0]}
    assert pi(obs[0]).shape == (6,) and np.allclose(pi(batch), [pi(o) for o in obs], atol=1e-6)
    assert env.action_space.contains(pi(obs[0]).astype(np.float32))
    env.close()
