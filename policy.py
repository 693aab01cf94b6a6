"""policy.py: the task-attention multimodal residual policy (TA-MRP, paper Sec. 4.2.2) and a
hand-written soft actor-critic (Sec. 4.3.2, Algorithm 1), torch and numpy only.

Observations are dicts of arrays, as the env gives them (batched: a leading B):
    image        (1, 80, 80) uint8    the task-attention ROI, gray
    pose_hist    (32, 6) float32      tip pose relative to X^_g [x y z rx ry rz], newest last
    wrench_hist  (32, 6) float32      wrist wrench [Fx Fy Fz Tx Ty Tz], newest last
Actions are 6-D in [-1, 1] (the env maps them to F_d).

The encoder (Fig. 4) turns each modality into 6-d features, fused by LayerNorm and tanh:
    image          -> 3-layer CNN, kernels 4/5/8, strides 3/3/4 (growing, as the paper says) -> 6
    pose + wrench  -> 2-layer LSTM, 64 hidden, over the 32 steps of both series side by side -> 12
The paper's 18-d fusion vector from "a 6-d image feature" and "6-d time-series features" we read as
6 + 6 + 6, a pose and a touch feature from the one LSTM it names (README difference 8). The ablation's
variants (--obs): ts-ptv (the method, 18-d), ts-pt (no image, 12), pt (the current pose and wrench through
an MLP, 12), v (the image alone, 6), ts-ptk (keypoint RL: the hole's keypoint for the image, 18).

Critics: multimodal ones on the actor's encoder as the paper's are, with what we added for them to learn, or
privileged ones (StateEncoder), which read a state vector only training knows; the actor never reads it (SAC's
docstring). Every hyper-parameter's
default is the one tacrl.py trains with.
"""
import copy
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

OBS_KINDS = ("pt", "ts-pt", "ts-ptv", "v", "ts-ptk")   # ts-ptk: keypoint RL (Table 1), the hole as a keypoint
FEAT = 6                      # features per modality
LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0


def mlp(n_in, n_out, hidden=(256, 256), norm=False):
    """Linear -> ReLU layers (norm: Linear -> LayerNorm -> ReLU, as RLPD's critics, Ball et al. 2023) -> Linear."""
    layers, d = [], n_in
    for h in hidden:
        layers += [nn.Linear(d, h), *([nn.LayerNorm(h)] if norm else []), nn.ReLU()]
        d = h
    return nn.Sequential(*layers, nn.Linear(d, n_out))


# ---------------------------------------------------------------- the multimodal encoder
IMAGE_NORMS = ("fixed", "image")
NORMS_COMMIT = "142e412"       # the commit that holds --image-norm local (issue 53: it lost to the image norm)


def pixels(img, norm="fixed"):
    """(B, 1, 80, 80) uint8 -> float: x / 255 - 0.5 (fixed), or (image, ours) each image minus its
    mean over its standard deviation (+ one grey level, for a flat image), so that light or paint that scales and
    shifts the grey levels leaves the input as it was: the normalisation of normalised cross-correlation, a classic
    of template matching under changing light (e.g. Lewis 1995)."""
    x = img.float() / 255.0
    if norm == "image":
        return (x - x.mean((2, 3), keepdim=True)) / (x.std((2, 3), keepdim=True) + 1 / 255)
    return x - 0.5


class ImageEncoder(nn.Module):
    """3-layer CNN, growing kernels and strides: (B, 1, 80, 80) -> (B, 8, 26, 26) -> (B, 16, 8, 8) -> (B, 32, 1, 1)
    -> (B, 6). The last kernel spans the whole 8 x 8 map, so every pixel reaches the feature. Small for 2 CPU
    cores (README difference 9)."""

    def __init__(self, img=80, norm="fixed"):
        super().__init__()
        self.norm = norm
        self.conv = nn.Sequential(nn.Conv2d(1, 8, 4, stride=3), nn.ReLU(), nn.Conv2d(8, 16, 5, stride=3), nn.ReLU(),
                                  nn.Conv2d(16, 32, 8, stride=4), nn.ReLU(), nn.Flatten())
        with torch.no_grad():
            self.fc = nn.Linear(self.conv(torch.zeros(1, 1, img, img)).shape[1], FEAT)

    def forward(self, img):                  # img: (B, 1, 80, 80) uint8
        return self.fc(self.conv(pixels(img, self.norm)))


class SeriesEncoder(nn.Module):
    """2-layer LSTM, 64 hidden, over (B, 32, n_in) -> last hidden state -> (B, n_out)."""

    def __init__(self, n_in=12, n_out=2 * FEAT, hidden=64):
        super().__init__()
        self.lstm = nn.LSTM(n_in, hidden, num_layers=2, batch_first=True)
        self.fc = nn.Linear(hidden, n_out)

    def forward(self, x):
        out, _ = self.lstm(x)
        return self.fc(out[:, -1])


class Encoder(nn.Module):
    """obs dict -> fused feature (B, out_dim). pose_scale, wrench_scale (6,): divide the raw SI
    readings by these so that the inputs are of order 1 (the env's error range and F_max)."""

    def __init__(self, kind="ts-ptv", pose_scale=np.ones(6), wrench_scale=np.ones(6), img=80, norm="joint",
                 image_norm="fixed"):
        super().__init__()
        if image_norm not in IMAGE_NORMS:
            raise ValueError(f"unknown image normalisation {image_norm!r} ({', '.join(IMAGE_NORMS)}; others: commit "
                             f"{NORMS_COMMIT})")
        if kind not in OBS_KINDS:
            raise ValueError(f"unknown observation kind {kind!r} ({', '.join(OBS_KINDS)})")
        self.kind, self.norm_kind, self.image_norm = kind, norm, image_norm
        self.register_buffer("pose_scale", torch.as_tensor(np.asarray(pose_scale), dtype=torch.float32))
        self.register_buffer("wrench_scale", torch.as_tensor(np.asarray(wrench_scale), dtype=torch.float32))
        if kind == "pt":
            self.now = mlp(12, 2 * FEAT, (64,))
        elif kind != "v":
            self.series = SeriesEncoder()
        self.image = ImageEncoder(img, image_norm) if kind in ("ts-ptv", "v") else None
        # ts-ptk (keypoint RL): obs['keypoint'] (B, 4), the hole found in the image by a detector, in place of the CNN
        self.keypoint = mlp(4, FEAT, (32,)) if kind == "ts-ptk" else None
        self.out_dim = {"ts-ptv": 3 * FEAT, "ts-ptk": 3 * FEAT, "v": FEAT}.get(kind, 2 * FEAT)
        # norm 'joint': one LayerNorm over the fused vector; 'modality': one per modality's features before
        # they are joined (SERL and SAC-AE end each modality's encoder in LayerNorm + tanh), so that the CNN's
        # 6 and the LSTM's 12 features enter at the same scale
        seen = self.image is not None or self.keypoint is not None                 # the image's, or the keypoint's, 6
        series = 2 * FEAT if kind != "v" else 0
        sizes = ([series] if series else []) + ([self.out_dim - series] if seen else [])
        self.norm = nn.LayerNorm(self.out_dim) if norm == "joint" else nn.ModuleList([nn.LayerNorm(n) for n in sizes])

    def forward(self, obs):
        z = []
        if self.kind != "v":
            pose = obs["pose_hist"] / self.pose_scale          # (B, 32, 6)
            wrench = obs["wrench_hist"] / self.wrench_scale    # (B, 32, 6)
        if self.kind == "pt":
            z = [self.now(torch.cat([pose[:, -1], wrench[:, -1]], 1))]
        elif self.kind != "v":
            z = [self.series(torch.cat([pose, wrench], 2))]     # (B, 12): pose and touch features
        if self.image is not None:
            z.append(self.image(obs["image"]))
        if self.keypoint is not None:
            z.append(self.keypoint(obs["keypoint"]))
        if self.norm_kind != "joint":
            return torch.tanh(torch.cat([ln(x) for ln, x in zip(self.norm, z)], 1))
        return torch.tanh(self.norm(torch.cat(z, 1)))       # the fusion vector, (B, 18) for ts-ptv


class StateEncoder(nn.Module):
    """The privileged critic's input (an asymmetric actor-critic, not in the paper): obs -> (B, 24 +
    state_dim) = the last two pose and wrench readings (scaled) and obs['state'], a vector the training
    loop computes from what the simulator knows and the policy does not (tacrl: X - X_g, the quantity
    Eq. 17's reward is made of, and the time). No learned weights: the Q heads' MLPs do the work."""

    def __init__(self, state_dim, pose_scale=np.ones(6), wrench_scale=np.ones(6)):
        super().__init__()
        self.register_buffer("pose_scale", torch.as_tensor(np.asarray(pose_scale), dtype=torch.float32))
        self.register_buffer("wrench_scale", torch.as_tensor(np.asarray(wrench_scale), dtype=torch.float32))
        self.out_dim = 24 + state_dim

    def forward(self, obs):
        pose = (obs["pose_hist"][:, -2:] / self.pose_scale).flatten(1)           # (B, 12)
        wrench = (obs["wrench_hist"][:, -2:] / self.wrench_scale).flatten(1)     # (B, 12)
        return torch.cat([pose, wrench, obs["state"]], 1)


# ---------------------------------------------------------------- actor and critics
class Actor(nn.Module):
    """Fusion vector -> 2 x 256 MLP -> mean and log-std of a 6-d Gaussian, squashed by tanh."""

    def __init__(self, n_feat, act_dim=6):
        super().__init__()
        self.net = mlp(n_feat, 2 * act_dim)

    def forward(self, z, deterministic=False, with_logp=True):
        mu, log_std = self.net(z).chunk(2, -1)
        log_std = LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (torch.tanh(log_std) + 1)
        u = mu if deterministic else mu + log_std.exp() * torch.randn_like(mu)
        a = torch.tanh(u)
        if not with_logp:
            return a, None
        # log pi(a) of the squashed Gaussian: log N(u) - sum log(1 - tanh(u)^2), written stably
        logp = (-0.5 * ((u - mu) / log_std.exp()) ** 2 - log_std - 0.5 * np.log(2 * np.pi)).sum(-1)
        logp = logp - (2 * (np.log(2) - u - F.softplus(-2 * u))).sum(-1)
        return a, logp


class TwinQ(nn.Module):
    """Two Q heads, each a 2 x 256 MLP on [fusion vector, action] (norm: LayerNorm after each hidden layer)."""

    def __init__(self, n_feat, act_dim=6, norm=False):
        super().__init__()
        self.q1, self.q2 = (mlp(n_feat + act_dim, 1, norm=norm) for _ in range(2))

    def forward(self, z, a):
        za = torch.cat([z, a], -1)
        return self.q1(za).squeeze(-1), self.q2(za).squeeze(-1)


@torch.no_grad()
def act(enc, actor, obs, deterministic=False, device="cpu"):
    """One env observation (a dict of arrays, pose_hist (HIST, 6)) -> action (6,) in [-1, 1]; a batch of them, each
    array with a leading axis B (a vector env's: pose_hist (B, HIST, 6)) -> (B, 6)."""
    one = np.ndim(obs["pose_hist"]) == 2
    o = {k: torch.as_tensor(np.asarray(v)[None] if one else np.asarray(v), device=device) for k, v in obs.items()}
    a = actor(enc(o), deterministic, with_logp=False)[0].cpu().numpy()
    return a[0] if one else a


# ---------------------------------------------------------------- replay buffer
class ReplayBuffer:
    """Ring buffer of transitions (o, a, r, o', terminated), images as uint8 (6.4 kB each); o' is stored beside o,
    twice the memory for a plain index. i: the next slot to write; n: the transitions held."""

    def __init__(self, capacity, obs_shapes, act_dim=6):
        self.capacity, self.n, self.i = capacity, 0, 0
        self.obs = {k: np.zeros((capacity, *s), np.uint8 if k == "image" else np.float32)
                    for k, s in obs_shapes.items()}
        self.next_obs = {k: np.zeros_like(v) for k, v in self.obs.items()}
        self.act = np.zeros((capacity, act_dim), np.float32)
        self.rew = np.zeros(capacity, np.float32)
        self.term = np.zeros(capacity, np.float32)

    def __len__(self):
        return self.n

    def add_episode(self, ep):
        """ep: {'obs': {k: (T + 1, ...)}, 'act': (T, 6), 'rew': (T,), 'term': (T,)}: the T + 1
        observations of one episode and its T transitions; obs keys the buffer was not built for are
        ignored."""
        T = len(ep["act"])
        j = (self.i + np.arange(T)) % self.capacity          # the slots this episode takes
        for k in self.obs:
            self.obs[k][j] = ep["obs"][k][:T]
            self.next_obs[k][j] = ep["obs"][k][1:]
        self.act[j], self.rew[j], self.term[j] = ep["act"], ep["rew"], ep["term"]
        self.i = (self.i + T) % self.capacity
        self.n = min(self.n + T, self.capacity)

    def sample(self, batch, rng, jitter_s=0.0):
        """A batch of transitions (o, a, r, o', terminated); with jitter_s, their images jittered (--augment)."""
        idx = rng.integers(0, self.n, batch)
        o, o2 = ({k: v[idx] for k, v in d.items()} for d in (self.obs, self.next_obs))
        if jitter_s and "image" in o:           # o and o' jittered independently, as DrQ does
            o["image"], o2["image"] = jitter(o["image"], rng, jitter_s), jitter(o2["image"], rng, jitter_s)
        return o, self.act[idx], self.rew[idx], o2, self.term[idx]


def jitter(images, rng, s):
    """Photometric augmentation of gray images (B, 1, H, W) uint8: each image's brightness, then its contrast about
    its mean, scaled by U(1 - s, 1 + s), as the brightness and contrast of RAD's colour jitter (Laskin et al.
    2020). Not the paper's method, which claims to need none: tacrl's --augment (README difference 17)."""
    per_image = (len(images),) + (1,) * (images.ndim - 1)
    x = images.astype(np.float32) * rng.uniform(1 - s, 1 + s, per_image).astype(np.float32)
    m = x.mean(axis=tuple(range(1, images.ndim)), keepdims=True)
    x = (x - m) * rng.uniform(1 - s, 1 + s, per_image).astype(np.float32) + m
    return np.clip(np.rint(x), 0, 255).astype(np.uint8)


# ---------------------------------------------------------------- the CPU: two cores in one update
class Helper:
    """A second thread for the second half of a batch (threads=2), or none (threads=1: the halves one after the
    other on this thread). Torch runs each op on the thread that calls it when torch.set_num_threads(1) (the caller
    sets it; the helper's thread sets its own), so the arithmetic is the same with one thread or two."""

    def __init__(self, threads=1):
        self.threads = threads
        self.pool = ThreadPoolExecutor(1, initializer=torch.set_num_threads, initargs=(1,)) if threads > 1 else None

    def both(self, f, x0, x1):
        """(f(x0), f(x1)), f(x1) on the helper's thread while this one computes f(x0)."""
        if self.pool is None:
            return f(x0), f(x1)
        job = self.pool.submit(f, x1)
        return f(x0), job.result()

    def __deepcopy__(self, memo):           # a copy of the SAC gets a thread of its own
        return Helper(self.threads)


def in_halves(f, params, o, helper):
    """f(o) for a batch dict o, computed as its two halves, side by side with a helper of two threads; the
    gradient reaches params (f's parameters) as from f(o). Two halves, with one thread or two: the same numbers."""
    n = len(next(iter(o.values()))) // 2
    if n == 0:                                      # a batch of one
        return f(o)
    halves = [{k: v[:n] for k, v in o.items()}, {k: v[n:] for k, v in o.items()}]
    if not torch.is_grad_enabled():                 # (grad mode is per thread)
        return torch.cat(helper.both(torch.no_grad()(f), *halves))
    return _Halves.apply(f, helper, halves, *params)


class _Halves(torch.autograd.Function):
    """Autograd for in_halves: each half keeps its own graph, and the backward runs the two side by side
    (torch.autograd.grad of each, summed: no two threads accumulate into one .grad)."""

    @staticmethod
    def forward(ctx, f, helper, halves, *params):
        def forward_half(x):
            with torch.enable_grad():       # grad mode is per thread, and off inside an autograd.Function
                return f(x)
        ctx.ys, ctx.helper, ctx.params = helper.both(forward_half, *halves), helper, params
        return torch.cat([y.detach() for y in ctx.ys])

    @staticmethod
    def backward(ctx, g):
        g0, g1 = g.split([len(y) for y in ctx.ys])
        d0, d1 = ctx.helper.both(lambda yg: torch.autograd.grad(yg[0], ctx.params, yg[1], allow_unused=True),
                                 (ctx.ys[0], g0), (ctx.ys[1], g1))
        ctx.ys = None
        return (None, None, None, *[a if b is None else b if a is None else a + b for a, b in zip(d0, d1)])


# ---------------------------------------------------------------- soft actor-critic
def td_target(r, terminated, q_next, logp_next, alpha, gamma):
    """y = r + gamma (1 - terminated) (min Q'(s', a') - alpha log pi(a'|s')). Only a real end of the
    task (success) cuts the bootstrap; an episode cut by the time limit (truncated) is stored with
    terminated = 0, because the state it stopped in still has a future."""
    return r + gamma * (1.0 - terminated) * (q_next - alpha * logp_next)


TAU, INIT_ALPHA = 0.005, 0.1       # Polyak rate of the target critics; the temperature's start (README difference 10)


class SAC:
    """SAC (Haarnoja et al. 2018) with twin Q, target critics (Polyak) and automatic temperature.

    Critics, with state_dim 0: multimodal, twin Q on the multimodal encoder as the paper's, which the actor reads
    with the gradient stopped (SAC-AE, DrQ); ours besides, as they learned best here (docs/critics.md): a LayerNorm
    over each modality's features and after each hidden layer of the Q heads (RLPD, Ball et al. 2023), and
    obs['extra'] (extra_dim,) beside the features, what the agent knows and the actor does not read. With
    state_dim > 0, privileged (Pinto et al. 2018; not the paper's): StateEncoder(obs), obs['state'] (state_dim,)
    included, and the actor has a multimodal encoder of its own, trained by the actor loss. Either way o' is read by the critics' online encoder
    without gradient (DrQ-v2, Yarats et al. 2021).

    On the CPU each multimodal encoder reads a batch as its two halves (encode, in_halves), with threads=2 side by
    side on two cores. Call torch.set_num_threads(1) first (command.use_cpu), so that each op runs on the thread
    that calls it: the numbers are then the same with threads=1 or 2.
    """

    def __init__(self, obs_kind="ts-ptv", pose_scale=np.ones(6), wrench_scale=np.ones(6), act_dim=6, lr=3e-4,
                 gamma=0.95, target_entropy=None, state_dim=0, extra_dim=0, image_norm="fixed", threads=1,
                 device="cpu"):
        self.device, self.gamma, self.extra_dim = torch.device(device), gamma, extra_dim
        self.helper = Helper(threads)        # threads=2: each multimodal encoder's batch as two halves, side by side
        self.shared = not state_dim          # multimodal critics lend the actor their encoder, as the paper's
        enc = lambda norm: Encoder(obs_kind, pose_scale, wrench_scale, norm=norm,  # noqa: E731
                                   image_norm=image_norm).to(self.device)
        self.enc = StateEncoder(state_dim, pose_scale, wrench_scale).to(self.device) if state_dim else enc("modality")
        self.q = TwinQ(self.enc.out_dim + extra_dim, act_dim, norm=self.shared).to(self.device)
        self.q_targ = copy.deepcopy(self.q)
        for p in self.q_targ.parameters():
            p.requires_grad_(False)
        self.actor_enc = self.enc if self.shared else enc("joint")      # what the actor reads: never obs['state']
        self.actor = Actor(self.actor_enc.out_dim, act_dim).to(self.device)
        self.log_alpha = torch.tensor(np.log(INIT_ALPHA), dtype=torch.float32, device=self.device, requires_grad=True)
        self.target_entropy = -float(act_dim) if target_entropy is None else float(target_entropy)
        # fused Adam: one kernel a step for all parameters; the same Adam to rounding (1.5e-7 apart after 10
        # updates), 1.06x the updates/s of foreach=True here (bench/bench_update.py)
        self.q_opt = torch.optim.Adam(list(self.enc.parameters()) + list(self.q.parameters()), lr=lr, fused=True)
        actor_params = list(self.actor.parameters()) + ([] if self.shared else list(self.actor_enc.parameters()))
        self.pi_opt = torch.optim.Adam(actor_params, lr=lr, fused=True)
        self.alpha_opt = torch.optim.Adam([self.log_alpha], lr=lr, fused=True)

    def act(self, obs, deterministic=False):
        """One env observation (unbatched dict) -> action (6,) in [-1, 1]."""
        return act(self.actor_enc, self.actor, obs, deterministic, self.device)

    def parameter_counts(self):
        n = lambda *ms: sum(p.numel() for m in ms for p in m.parameters())   # noqa: E731
        shared = ", shared with the critics" if self.shared else ""
        return (f"actor {n(self.actor_enc, self.actor):,} (encoder {n(self.actor_enc):,}{shared}), "
                f"critics {n(self.enc, self.q):,} (encoder {n(self.enc):,}, twin Q {n(self.q):,})")

    def update(self, batch):
        """One gradient step on a batch from ReplayBuffer.sample, (o, a, r, o', terminated); returns the losses."""
        o, a, r, o2, term = batch
        o, o2 = ({k: torch.as_tensor(v, device=self.device) for k, v in x.items()} for x in (o, o2))
        a, r, term = (torch.as_tensor(x, device=self.device) for x in (a, r, term))
        alpha = self.log_alpha.exp().detach()
        # critics: regress Q(o, a) on the TD target y (td_target)
        with torch.no_grad():
            z2 = self.encode(self.enc, o2)                                        # (B, n_feat)
            a2, logp2 = self.actor(z2 if self.shared else self.encode(self.actor_enc, o2))
            y = td_target(r, term, torch.min(*self.q_targ(self.critic_input(z2, o2), a2)), logp2, alpha, self.gamma)
        z = self.encode(self.enc, o)
        q_loss = sum(F.mse_loss(q, y) for q in self.q(self.critic_input(z, o), a))
        self.q_opt.zero_grad(set_to_none=True)
        q_loss.backward()
        self.q_opt.step()

        # actor: maximise min Q(o, pi(o)) - alpha log pi, the critics only read
        z_pi = z.detach() if self.shared else self.encode(self.actor_enc, o)
        a_pi, logp = self.actor(z_pi)
        for p in self.q.parameters():
            p.requires_grad_(False)
        q_pi = self.q(self.critic_input(z.detach(), o), a_pi)
        for p in self.q.parameters():
            p.requires_grad_(True)
        pi_loss = (alpha * logp - torch.min(*q_pi)).mean()
        self.pi_opt.zero_grad(set_to_none=True)
        pi_loss.backward()
        self.pi_opt.step()

        # temperature: towards the target entropy
        alpha_loss = -(self.log_alpha * (logp.detach() + self.target_entropy)).mean()
        self.alpha_opt.zero_grad(set_to_none=True)
        alpha_loss.backward()
        self.alpha_opt.step()

        with torch.no_grad():   # Polyak averaging of the target critics: p_targ <- (1 - tau) p_targ + tau p
            for p_targ, p in zip(self.q_targ.parameters(), self.q.parameters()):
                p_targ.lerp_(p, TAU)
        return {"q_loss": q_loss.item(), "pi_loss": pi_loss.item(), "alpha": alpha.item(),
                "entropy": -logp.mean().item()}

    def encode(self, enc, o):
        """enc(o); a multimodal encoder on the CPU as the batch's two halves (in_halves): its LSTM and CNN, most of
        an update, on two cores with threads=2, with the same numbers on one."""
        if self.device.type == "cpu" and isinstance(enc, Encoder):
            return in_halves(enc, [p for p in enc.parameters() if p.requires_grad], o, self.helper)
        return enc(o)

    def critic_input(self, z, o):
        """What the twin Q heads read: the critics' features, and with extra_dim obs['extra'] (B, extra_dim), a
        vector the actor does not read (tacrl: the time and the curriculum's ranges, which the agent knows)."""
        return torch.cat([z, o["extra"]], 1) if self.extra_dim else z

    # -- checkpoints -------------------------------------------------------------------
    def modules(self):
        m = {"enc": self.enc, "q": self.q, "q_targ": self.q_targ, "actor": self.actor, "q_opt": self.q_opt,
             "pi_opt": self.pi_opt, "alpha_opt": self.alpha_opt}
        if not self.shared:
            m["actor_enc"] = self.actor_enc
        return m

    def state_dict(self):
        d = {k: v.state_dict() for k, v in self.modules().items()}
        d["log_alpha"] = self.log_alpha.detach().cpu()
        return d

    def load_state_dict(self, d):
        for k, v in self.modules().items():
            v.load_state_dict(d[k])
        with torch.no_grad():
            self.log_alpha.copy_(d["log_alpha"])
