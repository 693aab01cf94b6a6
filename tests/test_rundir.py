"""rundir.py: the replay ring on disk, rebuilt slot by slot after a restart, and the update-time probe
for the first ETA. (The whole run directory, killed and resumed, is tests/test_train.py's.)"""
import os

import numpy as np
import pytest
import torch

import policy
import rundir


def fake_obs(rng, n):
    return {"image": rng.integers(0, 256, (n, 1, 80, 80), dtype=np.uint8),
            "pose_hist": rng.normal(0, 0.01, (n, 32, 6)).astype(np.float32),
            "wrench_hist": rng.normal(0, 1, (n, 32, 6)).astype(np.float32)}


def test_replay_files_rebuild_the_ring_exactly_and_keep_only_what_it_holds(tmp_path):
    rng = np.random.default_rng(4)
    shapes = {"image": (1, 80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6)}
    buf, files = policy.ReplayBuffer(25, shapes), rundir.ReplayFiles(str(tmp_path), 25, shapes)
    for n in range(1, 5):                                           # four episodes of 10: the ring holds 25
        ep = {"obs": fake_obs(rng, 11), "act": rng.uniform(-1, 1, (10, 6)), "rew": rng.normal(size=10),
              "term": np.zeros(10)}
        buf.add_episode(ep)
        files.add(ep, n)
        if n == 3:
            state3 = files.state(buf)                               # a checkpoint after episode 3
    assert [name for name, _ in state3["files"]] == ["ep_000001.npz", "ep_000002.npz", "ep_000003.npz"]
    files.prune()                                                   # after episode 4's checkpoint: 1 is overwritten
    assert sorted(os.listdir(tmp_path)) == ["ep_000002.npz", "ep_000003.npz", "ep_000004.npz"]
    again = policy.ReplayBuffer(25, shapes)
    rundir.ReplayFiles(str(tmp_path), 25, shapes).restore(again, files.state(buf))   # every transition in its slot
    for k in ("act", "rew", "term"):
        np.testing.assert_array_equal(getattr(again, k), getattr(buf, k))
    np.testing.assert_array_equal(again.obs["image"], buf.obs["image"])
    assert (again.i, again.n) == (buf.i, buf.n)
    with pytest.raises(ValueError, match="ep_000001.npz is missing"):   # episode 3's checkpoint needs file 1
        rundir.ReplayFiles(str(tmp_path), 25, shapes).restore(policy.ReplayBuffer(25, shapes), state3)
    (tmp_path / "ep_000003.npz").write_bytes(b"")                   # truncated to nothing
    with pytest.raises(ValueError, match="ep_000003.npz is damaged"):
        rundir.ReplayFiles(str(tmp_path), 25, shapes).restore(policy.ReplayBuffer(25, shapes), files.state(buf))


def test_a_replay_file_from_before_the_image_had_its_channel_axis_restores(tmp_path):
    rng, shapes = np.random.default_rng(5), {"image": (1, 80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6)}
    ep = {"obs": fake_obs(rng, 11), "act": rng.uniform(-1, 1, (10, 6)), "rew": rng.normal(size=10),
          "term": np.zeros(10)}
    buf, files = policy.ReplayBuffer(25, shapes), rundir.ReplayFiles(str(tmp_path), 25, shapes)
    buf.add_episode(ep)
    files.add({**ep, "obs": {**ep["obs"], "image": ep["obs"]["image"][:, 0]}}, 1)      # stored (11, 80, 80)
    again = policy.ReplayBuffer(25, shapes)
    rundir.ReplayFiles(str(tmp_path), 25, shapes).restore(again, files.state(buf))
    np.testing.assert_array_equal(again.obs["image"], buf.obs["image"])


def test_update_seconds_leaves_the_networks_and_the_random_numbers_as_they_were():
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv")
    before = [p.clone() for p in sac.actor.parameters()]
    state = torch.get_rng_state()
    o = {"image": np.zeros((8, 1, 80, 80), np.uint8), "pose_hist": np.zeros((8, 32, 6), np.float32),
         "wrench_hist": np.zeros((8, 32, 6), np.float32)}
    assert rundir.update_seconds(sac, (o, np.zeros((8, 6), np.float32), np.zeros(8, np.float32), o,
                                       np.zeros(8, np.float32))) > 0
    assert all(torch.equal(a, b) for a, b in zip(before, sac.actor.parameters()))
    assert torch.equal(torch.get_rng_state(), state)
