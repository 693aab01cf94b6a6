"""policy.py without pybullet: shapes of the TA-MRP networks, the squashed Gaussian's log-density,
the TD target's time-out handling, the replay buffer, checkpoints, and SAC solving a toy task."""
import io

import numpy as np
import pytest
import torch

import policy


def fake_obs(rng, n=None, kinds=("image", "pose_hist", "wrench_hist")):
    lead = () if n is None else (n,)
    o = {"image": rng.integers(0, 256, lead + (80, 80), dtype=np.uint8),
         "pose_hist": rng.normal(0, 0.01, lead + (32, 6)).astype(np.float32),
         "wrench_hist": rng.normal(0, 1, lead + (32, 6)).astype(np.float32)}
    return {k: o[k] for k in kinds}


@pytest.mark.parametrize("kind,dim", [("ts-ptv", 18), ("ts-pt", 12), ("pt", 12), ("v", 6)])
def test_encoder_fusion_sizes(kind, dim):
    enc = policy.Encoder(kind)
    o = {k: torch.as_tensor(v) for k, v in fake_obs(np.random.default_rng(0), 5).items()}
    z = enc(o)
    assert z.shape == (5, dim) and enc.out_dim == dim
    assert torch.all(z.abs() <= 1)


def test_squashed_gaussian_log_density():
    torch.manual_seed(0)
    actor = policy.Actor(18)
    z = torch.randn(7, 18)
    a, logp = actor(z)
    assert a.shape == (7, 6) and torch.all(a.abs() < 1)
    # against torch.distributions: a = tanh(u), u ~ N(mu, std)
    mu, log_std = actor.net(z).chunk(2, -1)
    log_std = policy.LOG_STD_MIN + 0.5 * (policy.LOG_STD_MAX - policy.LOG_STD_MIN) * (torch.tanh(log_std) + 1)
    dist = torch.distributions.TransformedDistribution(
        torch.distributions.Normal(mu, log_std.exp()), [torch.distributions.TanhTransform()])
    a_c = a.clamp(-1 + 1e-6, 1 - 1e-6)
    torch.testing.assert_close(logp, dist.log_prob(a_c).sum(-1), atol=1e-3, rtol=1e-3)


def test_td_target_bootstraps_time_outs_only():
    r, q, logp = torch.tensor([1.0, 1.0]), torch.tensor([10.0, 10.0]), torch.tensor([-2.0, -2.0])
    y = policy.td_target(r, torch.tensor([0.0, 1.0]), q, logp, alpha=0.5, gamma=0.9)
    assert y[0].item() == pytest.approx(1.0 + 0.9 * (10.0 + 1.0))   # truncated: bootstrap
    assert y[1].item() == pytest.approx(1.0)                          # terminated: none


def test_replay_keeps_uint8_images_and_pairs_o_with_o_next():
    rng = np.random.default_rng(1)
    buf = policy.ReplayBuffer(50, {"image": (80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6)})
    assert buf.obs["image"].dtype == np.uint8
    for ep in range(3):
        obs = fake_obs(rng, 21)
        obs["pose_hist"][:, 0, 0] = np.arange(21) + 100 * ep       # a step counter
        buf.add_episode({"obs": obs, "act": rng.uniform(-1, 1, (20, 6)), "rew": np.arange(20.0),
                         "term": np.r_[np.zeros(19), 1.0]})
    assert len(buf) == 50                                           # 60 added, ring of 50
    o, a, r, o2, term, aux = buf.sample(200, rng)
    assert aux.shape == (200, 0)                                    # aux_dim 0 keeps none
    np.testing.assert_array_equal(o2["pose_hist"][:, 0, 0], o["pose_hist"][:, 0, 0] + 1)
    assert set(term[r == 19]) == {1.0} and set(term[r != 19]) == {0.0}


def test_checkpoint_round_trip_reproduces_actions():
    rng = np.random.default_rng(2)
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv", aux_dim=4)
    buf = policy.ReplayBuffer(100, {"image": (80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6)}, aux_dim=4)
    buf.add_episode({"obs": fake_obs(rng, 11), "act": rng.uniform(-1, 1, (10, 6)), "rew": rng.normal(size=10),
                     "term": np.zeros(10), "aux": rng.normal(size=(11, 4))})
    for _ in range(3):
        sac.update(buf.sample(8, rng))
    f = io.BytesIO()                                # through bytes, as ckpt.pt goes
    torch.save(sac.state_dict(), f)
    f.seek(0)
    sac2 = policy.SAC("ts-ptv", aux_dim=4)
    sac2.load_state_dict(torch.load(f, weights_only=True))
    o = fake_obs(rng)
    np.testing.assert_array_equal(sac.act(o, deterministic=True), sac2.act(o, deterministic=True))
    torch.manual_seed(5)
    a1 = sac.act(o)
    torch.manual_seed(5)
    np.testing.assert_array_equal(a1, sac2.act(o))                 # the sampled action too
    # and training goes on identically from the restored optimisers
    b = buf.sample(8, np.random.default_rng(3))
    torch.manual_seed(6)
    sac.update(b)
    torch.manual_seed(6)
    sac2.update(b)
    np.testing.assert_allclose(sac.act(o, deterministic=True), sac2.act(o, deterministic=True), atol=1e-6)


@pytest.mark.parametrize("privileged", [False, True])
def test_sac_solves_point_reaching(privileged):
    """1-D point: x' = clip(x + 0.25 a), r = -|x'|, 10-step episodes that end by time-out only.
    From random starts the learnt mean policy must bring the point within 0.05 of the origin
    (the initial policy's mean ends about 0.5 away). Privileged: the critics read StateEncoder's
    input, obs['state'] = [x] included, and the actor learns through an encoder of its own."""
    torch.manual_seed(0)
    rng = np.random.default_rng(0)

    def obs_of(x):
        pose = np.zeros((32, 6), np.float32)
        pose[-1, 0] = x
        o = {"pose_hist": pose, "wrench_hist": np.zeros((32, 6), np.float32)}
        if privileged:
            o["state"] = np.array([x], np.float32)
        return o

    sac = policy.SAC("pt", lr=1e-3, gamma=0.9, state_dim=1 if privileged else 0)
    if privileged:
        assert isinstance(sac.enc, policy.StateEncoder) and sac.actor_enc is not None and not sac.shared
    buf = policy.ReplayBuffer(2000, {k: v.shape for k, v in obs_of(0.0).items()})

    def rollout(deterministic):
        x = rng.uniform(-1, 1)
        obs, acts, rews = [obs_of(x)], [], []
        for _ in range(10):
            a = sac.act(obs[-1], deterministic)
            x = float(np.clip(x + 0.25 * a[0], -1, 1))
            obs.append(obs_of(x))
            acts.append(a)
            rews.append(-abs(x))
        return obs, acts, rews, abs(x)

    before = np.mean([rollout(True)[3] for _ in range(20)])
    for ep in range(12):
        obs, acts, rews, _ = rollout(False)
        buf.add_episode({"obs": {k: np.stack([o[k] for o in obs]) for k in obs[0]}, "act": np.array(acts),
                         "rew": np.array(rews), "term": np.zeros(10)})
        if ep >= 1:
            for _ in range(20):
                sac.update(buf.sample(64, rng))
    after = np.mean([rollout(True)[3] for _ in range(20)])
    assert before > 0.2
    assert after < 0.05, (before, after)


def test_aux_loss_teaches_the_cnn_where_a_feature_is():
    """The aux regression reaches the image: a bright 12 x 12 square at a random column, the target
    its column. After 100 updates on that loss (rewards all zero) the CNN must place it far better
    than the untrained net does (the loss falls below a quarter of its first value)."""
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    n = 201
    obs = fake_obs(rng, n)
    obs["image"][:] = 0
    col = rng.integers(0, 68, n)
    for i, c in enumerate(col):
        obs["image"][i, 34:46, c:c + 12] = 255
    target = np.stack([(col - 34) / 34.0] * 2, 1).astype(np.float32)
    buf = policy.ReplayBuffer(n, {k: v.shape[1:] for k, v in obs.items()}, aux_dim=2)
    buf.add_episode({"obs": obs, "act": np.zeros((n - 1, 6)), "rew": np.zeros(n - 1), "term": np.zeros(n - 1),
                     "aux": target})
    sac = policy.SAC("ts-ptv", lr=1e-3, aux_dim=2, aux_weight=1.0)
    losses = [sac.update(buf.sample(16, rng))["aux_loss"] for _ in range(100)]
    assert np.mean(losses[-20:]) < 0.25 * np.mean(losses[:5]), (losses[:5], losses[-20:])


def test_residual_prior_pulls_the_mean_action_to_zero():
    """With nothing to gain (zero rewards), --prior-weight drives the actor's mean to F_d = 0."""
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    obs = fake_obs(rng, 101, kinds=("pose_hist", "wrench_hist"))
    buf = policy.ReplayBuffer(100, {k: v.shape[1:] for k, v in obs.items()})
    buf.add_episode({"obs": obs, "act": rng.uniform(-1, 1, (100, 6)), "rew": np.zeros(100), "term": np.zeros(100)})
    sac = policy.SAC("pt", lr=1e-3, prior_weight=5.0)
    with torch.no_grad():
        sac.actor.net[-1].bias[:6] = 1.0                  # start far from zero: mean tanh(1) = 0.76
    for _ in range(150):
        sac.update(buf.sample(32, rng))
    o = {k: v[0] for k, v in obs.items()}
    assert np.abs(sac.act(o, deterministic=True)).max() < 0.1
