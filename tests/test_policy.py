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
    o = {"image": rng.integers(0, 256, lead + (1, 80, 80), dtype=np.uint8),
         "keypoint": rng.uniform(-0.5, 0.5, lead + (4,)).astype(np.float32),
         "pose_hist": rng.normal(0, 0.01, lead + (32, 6)).astype(np.float32),
         "wrench_hist": rng.normal(0, 1, lead + (32, 6)).astype(np.float32)}
    return {k: o[k] for k in kinds}


@pytest.mark.parametrize("kind,dim,norm,image_norm", [
    ("ts-ptv", 18, "joint", "fixed"), ("ts-pt", 12, "joint", "fixed"), ("pt", 12, "joint", "fixed"),
    ("v", 6, "joint", "fixed"), ("ts-ptk", 18, "joint", "fixed"), ("ts-ptk", 18, "modality", "fixed"),
    ("ts-ptv", 18, "modality", "fixed"), ("ts-ptv", 18, "joint", "image"), ("v", 6, "modality", "image")])
def test_encoder_fusion_sizes_and_modalities(kind, dim, norm, image_norm):
    enc = policy.Encoder(kind, norm=norm, image_norm=image_norm)
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


def test_replay_keeps_uint8_images_and_pairs_o_with_o_next():
    rng = np.random.default_rng(1)
    buf = policy.ReplayBuffer(50, {"image": (1, 80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6)})
    assert buf.obs["image"].dtype == np.uint8
    for ep in range(3):
        obs = fake_obs(rng, 21)
        obs["pose_hist"][:, 0, 0] = np.arange(21) + 100 * ep       # a step counter
        buf.add_episode({"obs": obs, "act": rng.uniform(-1, 1, (20, 6)), "rew": np.arange(20.0),
                         "term": np.r_[np.zeros(19), 1.0]})
    assert len(buf) == 50                                           # 60 added, ring of 50
    o, a, r, o2, term = buf.sample(200, rng)
    np.testing.assert_array_equal(o2["pose_hist"][:, 0, 0], o["pose_hist"][:, 0, 0] + 1)
    assert set(term[r == 19]) == {1.0} and set(term[r != 19]) == {0.0}
    # --augment: the sampled images jittered, o and o' each their own way; the buffer's own left as they were
    stored = buf.obs["image"].copy()
    o, _, _, o2, _ = buf.sample(200, np.random.default_rng(3), jitter_s=0.4)
    o_plain, _, _, o2_plain, _ = buf.sample(200, np.random.default_rng(3))
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
    buf = policy.ReplayBuffer(100, {"image": (1, 80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6)})
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


def small_buffer(rng, extra=False):
    buf = policy.ReplayBuffer(50, {"image": (1, 80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6),
                                   **({"extra": (3,)} if extra else {})})
    obs = {**fake_obs(rng, 11), "extra": rng.uniform(0, 1, (11, 3)).astype(np.float32)}
    buf.add_episode({"obs": obs, "act": rng.uniform(-1, 1, (10, 6)), "rew": rng.normal(size=10), "term": np.zeros(10)})
    return buf


def test_the_papers_critics_norm_each_modality_and_the_q_heads_and_read_the_extras():
    count = lambda m: sum(isinstance(x, torch.nn.LayerNorm) for x in m.modules())   # noqa: E731
    torch.manual_seed(0)
    paper, privileged = policy.SAC("ts-ptv", extra_dim=3), policy.SAC("ts-ptv", state_dim=7)
    assert count(paper.q) == 4 and count(privileged.q) == 0                  # 2 hidden layers x 2 heads
    assert paper.actor_enc is paper.enc and paper.enc.norm_kind == "modality" and count(paper.enc) == 2
    assert privileged.actor_enc.norm_kind == "joint" and count(privileged.actor_enc) == 1
    rng = np.random.default_rng(5)
    o, a, r, o2, term = small_buffer(rng, extra=True).sample(8, rng)
    before = [p.clone() for p in paper.q.parameters()]
    assert all(np.isfinite(v) for v in paper.update((o, a, r, o2, term)).values())
    assert all(not torch.equal(x, y) for x, y in zip(before, paper.q.parameters()))    # the norms learn too
    ot = {k: torch.as_tensor(v) for k, v in o.items()}
    z, at = paper.enc(ot), torch.as_tensor(a)
    q = lambda extra: paper.q(paper.critic_input(z, {"extra": extra}), at)[0]    # noqa: E731
    assert not torch.allclose(q(ot["extra"]), q(ot["extra"] + 1))            # the critics read obs['extra']
    obs = {k: v[0] for k, v in fake_obs(rng, 1).items()}
    assert paper.act(obs).shape == (6,)                                      # the actor reads no 'extra'


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
    buf = policy.ReplayBuffer(200, {"image": (1, 80, 80), "pose_hist": (32, 6), "wrench_hist": (32, 6), "state": (7,),
                                    "extra": (3,)})
    obs = {**fake_obs(rng, 101), "state": rng.normal(size=(101, 7)).astype(np.float32),
           "extra": rng.normal(size=(101, 3)).astype(np.float32)}
    buf.add_episode({"obs": obs, "act": rng.uniform(-1, 1, (100, 6)), "rew": rng.normal(size=100),
                     "term": np.zeros(100)})
    batch = buf.sample(64, rng)
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv", state_dim=state_dim, extra_dim=0 if state_dim else 3, threads=2)
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


def test_an_image_standardised_by_itself_reads_the_same_under_other_light():
    # a dimmer light or darker paint that scales and shifts the grey levels (x -> a x + b): the standardised input is
    # as it was, to a tenth of its spread (rounding to uint8), and the fixed one is not
    img = np.random.default_rng(0).integers(60, 160, (2, 1, 80, 80)).astype(np.float64)
    other = np.clip(np.rint(0.5 * img + 10), 0, 255)
    for norm, same in (("image", True), ("fixed", False)):
        a, b = (policy.pixels(torch.as_tensor(x.astype(np.uint8)), norm) for x in (img, other))
        assert bool((a - b).abs().max() < 0.1 * a.std()) == same, norm
