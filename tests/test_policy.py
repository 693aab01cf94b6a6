"""policy.py without pybullet: shapes of the TA-MRP networks, the squashed Gaussian's log-density,
the TD target's time-out handling, the replay buffer, checkpoints, what the actor may read, SAC
solving a toy task, and that it lifts out with numpy and torch alone."""
import ast
import copy
import io
import os
import sys

import numpy as np
import pytest
import torch

import policy

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def fake_obs(rng, n=None, kinds=("image", "pose_hist", "wrench_hist")):
    lead = () if n is None else (n,)
    o = {"image": rng.integers(0, 256, lead + (80, 80), dtype=np.uint8),
         "keypoint": rng.uniform(-0.5, 0.5, lead + (4,)).astype(np.float32),
         "pose_hist": rng.normal(0, 0.01, lead + (32, 6)).astype(np.float32),
         "wrench_hist": rng.normal(0, 1, lead + (32, 6)).astype(np.float32)}
    return {k: o[k] for k in kinds}


@pytest.mark.parametrize("kind,dim,norm,image", [
    ("ts-ptv", 18, "joint", "cnn"), ("ts-pt", 12, "joint", "cnn"), ("pt", 12, "joint", "cnn"), ("v", 6, "joint", "cnn"),
    ("ts-ptk", 18, "joint", "cnn"), ("ts-ptk", 18, "modality", "cnn"), ("ts-ptv", 18, "modality", "cnn"),
    ("ts-ptv", 18, "modality", "spatial"), ("v", 6, "joint", "spatial")])
def test_encoder_fusion_sizes_and_modalities(kind, dim, norm, image):
    enc = policy.Encoder(kind, norm=norm, image=image, image_norm="image" if image == "spatial" else "fixed")
    o = {k: torch.as_tensor(v) for k, v in fake_obs(np.random.default_rng(0), 5, ("image", "keypoint", "pose_hist",
                                                                                     "wrench_hist")).items()}
    z = enc(o)
    assert z.shape == (5, dim) and enc.out_dim == dim
    # each modality the variant names reaches the fused vector, and no other does
    for key, used in (("image", kind in ("ts-ptv", "v")), ("keypoint", kind == "ts-ptk"), ("pose_hist", kind != "v"),
                      ("wrench_hist", kind != "v")):
        o2 = dict(o)
        o2[key] = torch.flip(o[key], [0])          # other samples' data in this modality
        assert (not torch.allclose(enc(o2), z)) == used, key


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


def test_n_step_returns_sum_the_discounted_rewards_and_stop_at_the_episode_end():
    rng = np.random.default_rng(1)
    buf = policy.ReplayBuffer(10, {"pose_hist": (32, 6)}, nstep=3, gamma=0.5)
    obs = {"pose_hist": np.zeros((6, 32, 6), np.float32)}
    obs["pose_hist"][:, 0, 0] = np.arange(6)                       # a step counter
    buf.add_episode({"obs": obs, "act": rng.uniform(-1, 1, (5, 6)), "rew": np.array([1.0, 2, 4, 8, 16]),
                     "term": np.array([0, 0, 0, 0, 1.0])})          # success at the 5th step
    np.testing.assert_allclose(buf.rew[:5], [1 + 1 + 1, 2 + 2 + 2, 4 + 4 + 4, 8 + 8, 16])
    np.testing.assert_array_equal(buf.next_obs["pose_hist"][:5, 0, 0], [3, 4, 5, 5, 5])
    np.testing.assert_array_equal(buf.term[:5], [0, 0, 1, 1, 1])    # within 3 steps of the success: no bootstrap
    np.testing.assert_allclose(buf.disc[:5], [0.125, 0.125, 0.125, 0.25, 0.5])


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
    o, a, r, o2, term, disc = buf.sample(200, rng)
    np.testing.assert_array_equal(o2["pose_hist"][:, 0, 0], o["pose_hist"][:, 0, 0] + 1)
    assert set(term[r == 19]) == {1.0} and set(term[r != 19]) == {0.0}
    # --augment: the sampled images jittered, o and o' each their own way; the buffer's own left as they were
    stored = buf.obs["image"].copy()
    o, _, _, o2, _, _ = buf.sample(200, np.random.default_rng(3), jitter_s=0.4)
    o_plain, _, _, o2_plain, _, _ = buf.sample(200, np.random.default_rng(3))
    np.testing.assert_array_equal(buf.obs["image"], stored)
    np.testing.assert_array_equal(o["pose_hist"], o_plain["pose_hist"])
    assert o["image"].dtype == np.uint8 and not np.array_equal(o["image"], o_plain["image"])


def test_jitter_scales_brightness_and_contrast_within_its_range():
    img = np.full((2000, 8, 8), 100, np.uint8)
    img[:, :4] = 50                                     # mean 75, two levels 25 either side of it
    out = policy.jitter(img, np.random.default_rng(0), 0.4).astype(float)
    mean = out.reshape(len(out), -1).mean(1)            # brightness: 75 x U(0.6, 1.4)
    assert 0.6 * 75 - 1 <= mean.min() < 0.65 * 75 and 1.35 * 75 < mean.max() <= 1.4 * 75 + 1
    spread = (out[:, 7, 0] - out[:, 0, 0]) / 50          # contrast x brightness: within U(0.6, 1.4)^2
    assert 0.36 - 0.03 <= spread.min() < 0.45 and 1.8 < spread.max() <= 1.96 + 0.03


def test_checkpoint_round_trip_reproduces_actions():
    rng = np.random.default_rng(2)
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv")
    buf = policy.ReplayBuffer(100, {"image": (80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6)})
    buf.add_episode({"obs": fake_obs(rng, 11), "act": rng.uniform(-1, 1, (10, 6)), "rew": rng.normal(size=10),
                     "term": np.zeros(10)})
    for _ in range(3):
        sac.update(buf.sample(8, rng))
    f = io.BytesIO()                                # through bytes, as ckpt.pt goes
    torch.save(sac.state_dict(), f)
    f.seek(0)
    sac2 = policy.SAC("ts-ptv")
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


def test_layernorm_in_the_q_heads_only_where_asked():
    norms = lambda sac: sum(isinstance(m, torch.nn.LayerNorm) for m in sac.q.modules())   # noqa: E731
    assert norms(policy.SAC("ts-ptv")) == 0 and norms(policy.SAC("ts-ptv", q_norm=True)) == 4   # 2 hidden x 2 heads
    rng = np.random.default_rng(5)
    buf = policy.ReplayBuffer(50, {"image": (80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6)})
    buf.add_episode({"obs": fake_obs(rng, 11), "act": rng.uniform(-1, 1, (10, 6)), "rew": rng.normal(size=10),
                     "term": np.zeros(10)})
    sac = policy.SAC("ts-ptv", q_norm=True)
    before = [p.clone() for p in sac.q.parameters()]
    assert np.isfinite(sac.update(buf.sample(8, rng))["q_loss"])
    assert all(not torch.equal(a, b) for a, b in zip(before, sac.q.parameters()))    # the norms learn too


def small_buffer(rng):
    buf = policy.ReplayBuffer(50, {"image": (80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6)})
    buf.add_episode({"obs": fake_obs(rng, 11), "act": rng.uniform(-1, 1, (10, 6)), "rew": rng.normal(size=10),
                     "term": np.zeros(10)})
    return buf


def test_dropout_and_an_ensemble_of_q_heads_only_where_asked():
    count = lambda sac, kind: sum(isinstance(m, kind) for m in sac.q.modules())   # noqa: E731
    assert count(policy.SAC("ts-ptv"), torch.nn.Dropout) == 0
    assert count(policy.SAC("ts-ptv", q_dropout=0.01, q_norm=True), torch.nn.Dropout) == 4
    rng = np.random.default_rng(5)
    buf = small_buffer(rng)
    sac = policy.SAC("ts-ptv", n_q=5)
    assert len(sac.q(torch.zeros(3, 18), torch.zeros(3, 6))) == 5
    before = [p.clone() for p in sac.q.parameters()]
    assert np.isfinite(sac.update(buf.sample(8, rng))["q_loss"])
    assert all(not torch.equal(a, b) for a, b in zip(before, sac.q.parameters()))    # every head learns


def updated(batch, **kw):
    """SAC("ts-ptv", **kw) as seed 0 draws it, after one update on batch (the actor's samples from seed 1), and its
    critics' encoder's parameters: options that differ only there start from the same networks."""
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv", **kw)
    torch.manual_seed(1)
    assert np.isfinite(sac.update(batch)["q_loss"])
    return sac, [p.detach().clone() for p in sac.enc.parameters()]


def test_the_image_decoder_and_the_encoders_own_step_size_train_the_critics_encoder():
    rng = np.random.default_rng(9)
    b = small_buffer(rng).sample(8, rng)
    encs = [updated(b, **kw)[1] for kw in ({}, {"aux_recon": 1.0}, {"enc_lr": 1e-5})]
    torch.manual_seed(0)
    start = [p.detach().clone() for p in policy.SAC("ts-ptv").enc.parameters()]
    step = lambda e: max((p - p0).abs().max().item() for p, p0 in zip(e, start))   # noqa: E731
    assert not all(torch.equal(p, q) for p, q in zip(encs[0], encs[1]))           # the decoder's gradient reaches it
    assert step(encs[2]) < 0.1 * step(encs[0])                                     # Adam's step is about the lr


def test_curl_scores_the_positive_and_trains_the_critics_encoder():
    rng = np.random.default_rng(10)
    buf = small_buffer(rng)
    b = buf.sample(8, rng, positive=4)
    assert b[0]["image_pos"].shape == (8, 80, 80) and not np.array_equal(b[0]["image_pos"], b[0]["image"])
    encs = [updated(b, aux_curl=w)[1] for w in (0.0, 1.0)]
    assert not all(torch.equal(p, q) for p, q in zip(*encs))      # the contrastive gradient reaches it


def test_drq_copies_average_the_target_and_the_actor_reads_the_first():
    rng = np.random.default_rng(8)
    o, a, r, o2, term, disc = small_buffer(rng).sample(8, rng, shift=4, copies=2)
    assert len(a) == 16 and np.array_equal(a[:8], a[8:]) and not np.array_equal(o["image"][:8], o["image"][8:])
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv", copies=2)
    seen = []
    sac.actor.register_forward_hook(lambda m, args, out: seen.append(len(args[0])))
    assert np.isfinite(sac.update((o, a, r, o2, term, disc))["q_loss"])
    assert seen == [16, 8]              # a' for every copy of o'; the actor's loss on the first copy of o


def test_a_reset_redraws_the_heads_and_keeps_the_encoder():
    rng = np.random.default_rng(6)
    buf = small_buffer(rng)
    sac = policy.SAC("ts-ptv", q_norm=True)
    for _ in range(3):
        sac.update(buf.sample(8, rng))
    enc, q, actor = (copy.deepcopy(m.state_dict()) for m in (sac.enc, sac.q, sac.actor))
    sac.reset_heads()
    assert all(torch.equal(v, sac.enc.state_dict()[k]) for k, v in enc.items())
    for old, m in ((q, sac.q), (actor, sac.actor)):
        assert all(not torch.equal(v, m.state_dict()[k]) for k, v in old.items() if v.dtype.is_floating_point and
                   v.numel() > 1 and v.std() > 0)      # drawn anew (LayerNorm's ones and zeros stay)
    assert all(torch.equal(v, sac.q_targ.state_dict()[k]) for k, v in sac.q.state_dict().items())
    assert not any(p in sac.q_opt.state for p in sac.q.parameters())
    assert np.isfinite(sac.update(buf.sample(8, rng))["q_loss"])


def test_the_next_wrench_head_trains_the_critics_encoder():
    rng = np.random.default_rng(7)
    b = small_buffer(rng).sample(8, rng)
    (without, enc0), (with_head, enc1) = (updated(b, aux_wrench=w) for w in (0.0, 1.0))
    assert without.w_head is None and with_head.w_head is not None
    assert not all(torch.equal(p, q) for p, q in zip(enc0, enc1))


@pytest.fixture
def one_thread():
    """torch.set_num_threads(1) for the test, as tacrl runs: each op on the thread that calls it."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def one_update(sac, batch, seed=1):
    torch.manual_seed(seed)                        # the actor's samples
    losses = sac.update(batch)
    return losses, {f"{m}.{k}": v for m, d in sac.state_dict().items() if m.endswith(("enc", "q", "actor", "targ"))
                    for k, v in d.items()}


@pytest.mark.parametrize("state_dim", [0, 7])      # the paper's critics, the privileged ones
def test_an_update_in_halves_is_the_whole_batch_update_within_float_tolerance_on_one_thread_or_two(state_dim,
                                                                                                      one_thread):
    rng = np.random.default_rng(4)
    buf = policy.ReplayBuffer(200, {"image": (80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6), "state": (7,)})
    obs = {**fake_obs(rng, 101), "state": rng.normal(size=(101, 7)).astype(np.float32)}
    buf.add_episode({"obs": obs, "act": rng.uniform(-1, 1, (100, 6)), "rew": rng.normal(size=100), "term": np.zeros(100)})
    batch = buf.sample(64, rng)
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv", state_dim=state_dim, threads=2)
    whole, one = copy.deepcopy(sac), copy.deepcopy(sac)
    whole.encode = lambda enc, o: enc(o)           # the update before the halves: each encoder on the whole batch
    one.helper = policy.Helper(1)
    (l2, p2), (lw, pw), (l1, p1) = (one_update(s, batch) for s in (sac, whole, one))
    assert l2 == pytest.approx(lw, rel=1e-5) and p2.keys() == pw.keys()
    for k in pw:                                    # Adam's first step moves each weight by about 3e-4
        torch.testing.assert_close(p2[k], pw[k], atol=1e-6, rtol=1e-5, msg=k)
    assert l1 == l2 and all(torch.equal(p1[k], p2[k]) for k in p2)     # one thread or two: the same numbers


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


def test_the_actor_never_reads_what_only_the_critics_may():
    """Privileged critics read obs['state'] (X - X_g in tacrl); the deployed actor must not: its action
    is the same whatever the state holds, and the critics' value is not."""
    torch.manual_seed(0)
    rng = np.random.default_rng(3)
    sac = policy.SAC("ts-ptv", state_dim=3)
    assert sac.actor_enc is not sac.enc
    o = {**fake_obs(rng), "state": np.zeros(3, np.float32)}
    o2 = {**o, "state": np.array([5.0, -5.0, 1.0], np.float32)}
    np.testing.assert_array_equal(sac.act(o, deterministic=True), sac.act(o2, deterministic=True))
    batch = lambda x: {k: torch.as_tensor(v[None]) for k, v in x.items()}   # noqa: E731
    a = torch.zeros(1, 6)
    assert not torch.allclose(sac.q(sac.enc(batch(o)), a)[0], sac.q(sac.enc(batch(o2)), a)[0])


def module_imports(name):
    """The modules a file of the project imports when it is imported (its top-level import statements)."""
    tree = ast.parse(open(os.path.join(ROOT, f"{name}.py")).read())
    out = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            out.add(node.module.split(".")[0])
    return out


def test_the_liftable_modules_need_only_numpy_and_torch_and_the_core_no_plotting():
    for name in ("control", "curriculum", "policy"):
        assert module_imports(name) - set(sys.stdlib_module_names) <= {"numpy", "torch"}, name
    core = ("tacrl", "sim", "scene", "evaluate", "rundir", "baselines", "control", "curriculum", "policy")
    for name in core:           # matplotlib only inside rundir.plot_curves; tools/ is never imported
        assert not module_imports(name) & {"matplotlib", "report", "figures", "seeds", "tensorboard"}, name


def test_random_shift_moves_each_image_by_at_most_pad_pixels_repeating_its_edges():
    img = np.zeros((200, 20, 20), np.uint8)
    img[:, 10, 10] = 255                                   # one bright pixel, in the middle
    out = policy.random_shift(img, np.random.default_rng(0), 3)
    where = np.array([np.argwhere(x == 255)[0] for x in out])
    assert out.shape == img.shape and out.dtype == np.uint8
    assert np.abs(where - 10).max() == 3 and len(np.unique(where[:, 1])) == 7     # every shift in -3..3 drawn
    edge = np.tile(np.arange(20, dtype=np.uint8), (1, 20, 1))                    # columns 0..19
    shifted = policy.random_shift(edge, np.random.default_rng(1), 4)[0]
    assert set(np.diff(shifted[0]).tolist()) <= {0, 1}     # the left or right edge repeated, the rest in order


@pytest.mark.parametrize("norm", ["joint", "modality"])
def test_the_papers_critics_with_extras_and_the_online_next_encoder_update(norm):
    rng = np.random.default_rng(0)
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv", extra_dim=3, target_encoder=False, norm=norm, own_actor_encoder=norm == "modality",
                     aux_reward=1.0 if norm == "joint" else 0.0)
    assert (sac.actor_enc is sac.enc) == (norm == "joint")
    o, o2 = ({**fake_obs(rng, 16), "extra": rng.uniform(0, 1, (16, 3)).astype(np.float32)} for _ in range(2))
    losses = sac.update((o, rng.uniform(-1, 1, (16, 6)).astype(np.float32), rng.normal(size=16).astype(np.float32), o2,
                         np.zeros(16, np.float32)))
    assert all(np.isfinite(v) for v in losses.values())
    assert sac.act(fake_obs(rng)).shape == (6,)            # the actor reads no 'extra'


@pytest.mark.parametrize("image,image_norm,feat", [("cnn", "fixed", 6), ("cnn", "image", 6), ("spatial", "fixed", 6),
                                                   ("cnn", "fixed", 16)])
def test_a_saved_policy_keeps_its_encoders_layout(tmp_path, image, image_norm, feat):
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv", norm="modality", own_actor_encoder=True, image=image, image_norm=image_norm,
                     image_feat=feat)
    assert sac.actor_enc.out_dim == 12 + feat
    policy.save_policy(str(tmp_path / "p.pt"), sac, {"task": "peg", "obs": "ts-ptv"})
    pi = policy.TrainedPolicy(policy.load_file(str(tmp_path / "p.pt")))
    obs = fake_obs(np.random.default_rng(0))
    np.testing.assert_array_equal(pi(obs), sac.act(obs, deterministic=True))


def test_spatial_softmax_keypoints_follow_what_moves_in_the_image():
    # a bright square on a dark image, moved 12 px right: a sharp softmax's keypoints of the channels that peak on it
    # move right by 12 px in the map's [-1, 1] units and not down; a square that stays leaves every keypoint where it was
    torch.manual_seed(0)
    enc = policy.SpatialImageEncoder()
    with torch.no_grad():
        enc.log_temp.fill_(np.log(0.01))
    img = np.zeros((3, 80, 80), np.uint8)
    img[0, 30:40, 20:30] = img[1, 30:40, 32:42] = img[2, 30:40, 20:30] = 255
    kp = enc.keypoints(torch.as_tensor(img)).detach().numpy()           # (3, K, 2)
    n = enc.grid.shape[0] ** 0.5                                           # the map's side (12, strides 3 x 2)
    moved = kp[1] - kp[0]
    peaked = np.abs(moved[:, 0] - 12 / 6 * 2 / (n - 1)) < 0.05             # channels that track the square
    assert peaked.sum() >= 2
    np.testing.assert_allclose(moved[peaked, 1], 0, atol=0.05)
    np.testing.assert_allclose(kp[2], kp[0], atol=1e-6)


def test_an_image_standardised_by_itself_reads_the_same_under_other_light():
    # a dimmer light or darker paint that scales and shifts the grey levels (x -> a x + b): the standardised input is
    # as it was, to a tenth of its spread (rounding to uint8), and the fixed one is not
    img = np.random.default_rng(0).integers(60, 160, (2, 80, 80)).astype(np.float64)
    other = np.clip(np.rint(0.5 * img + 10), 0, 255)
    for norm, same in (("image", True), ("fixed", False)):
        a, b = (policy.pixels(torch.as_tensor(x.astype(np.uint8)), norm) for x in (img, other))
        assert bool((a - b).abs().max() < 0.1 * a.std()) == same, norm
