"""policy.py: the task-attention multimodal residual policy (TA-MRP, paper Sec. 4.2.2) and a
hand-written soft actor-critic (Sec. 4.3.2, Algorithm 1), torch and numpy only.

Observations are dicts of arrays, as the env gives them:
    image        (80, 80) uint8       the task-attention ROI, gray
    pose_hist    (32, 6) float32      tip pose relative to X^_g [x y z rx ry rz], newest last
    wrench_hist  (32, 6) float32      wrist wrench [Fx Fy Fz Tx Ty Tz], newest last
Batched, a leading B. Actions are 6-D in [-1, 1] (the env maps them to F_d).

The encoder (Fig. 4 of the paper) turns each modality into a 6-d feature and concatenates them:
    image          -> 3-layer CNN, kernels 4/5/8, strides 3/3/4 (growing, as the paper says) -> 6
                      (or, ours, --image-encoder spatial: keypoints by a spatial softmax -> 6)
    pose + wrench  -> 2-layer LSTM, 64 hidden, over the 32 steps of both series side by side
                      (12 inputs a step), last hidden state -> 12 = a 6-d pose and a 6-d touch feature
The paper fuses to an 18-d vector from "a 6-d image feature" and "6-d time-series features"; we
read that as one 6-d feature per time series (pose and touch), 6 + 6 + 6 = 18, from the one LSTM
the paper names. (Two LSTMs, one a series, cost twice as much per update on a CPU: the LSTM's 32
sequential steps dominate the update.) The observation
variants of the ablation (--obs) drop modalities:
    ts-ptv  image + pose history + wrench history   18-d   (the method)
    ts-pt   pose history + wrench history           12-d
    pt      current pose + wrench, an MLP           12-d
    v       image only (the 'visual' baseline)       6-d
The fused vector goes through LayerNorm and tanh, then the 2 x 256 heads.

Critics: either the paper's (twin Q on the same multimodal encoder, which the actor then reads with
the gradient stopped) or privileged ones (StateEncoder: the last pose and wrench readings plus a
state vector that only training knows, obs['state'], which the training loop fills; the actor then has
a multimodal encoder of its own). The actor is the same in both and never reads the state vector.

The replay buffer is a ring in memory (tacrl's rundir.py keeps its episodes on disk); the saved
policy (save_policy, TrainedPolicy) is the actor and its encoder with the caller's metadata.
Every hyper-parameter's default is the one tacrl.py trains with.
"""
import copy
import ctypes
import os
import pickle
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

OBS_KINDS = ("pt", "ts-pt", "ts-ptv", "v", "ts-ptk")   # ts-ptk: keypoint RL (Table 1), the hole as a keypoint
FEAT = 6                      # features per modality
LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0


def mlp(n_in, n_out, hidden=(256, 256), norm=False, dropout=0.0):
    """Linear -> ReLU layers (norm: Linear -> LayerNorm -> ReLU, as RLPD's critics, Ball et al. 2023; dropout:
    Linear -> Dropout -> [LayerNorm ->] ReLU, as DroQ's, Hiraoka et al. 2021) -> Linear."""
    layers, d = [], n_in
    for h in hidden:
        layers += [nn.Linear(d, h), *([nn.Dropout(dropout)] if dropout else []), *([nn.LayerNorm(h)] if norm else []),
                   nn.ReLU()]
        d = h
    return nn.Sequential(*layers, nn.Linear(d, n_out))


# ---------------------------------------------------------------- the multimodal encoder
IMAGE_NORMS = ("fixed", "image")


def pixels(img, norm="fixed"):
    """(B, 80, 80) uint8 -> (B, 1, 80, 80) float: x / 255 - 0.5 (fixed), or (image, ours) each image minus its
    mean over its standard deviation (+ one grey level, for a flat image), so that light or paint that scales and
    shifts the grey levels leaves the input as it was: the normalisation of normalised cross-correlation, a classic
    of template matching under changing light (e.g. Lewis 1995)."""
    x = img.unsqueeze(1).float() / 255.0
    if norm == "image":
        return (x - x.mean((2, 3), keepdim=True)) / (x.std((2, 3), keepdim=True) + 1 / 255)
    return x - 0.5


class ImageEncoder(nn.Module):
    """3-layer CNN, growing kernels and strides: (B, 1, 80, 80) -> (B, 8, 26, 26) -> (B, 16, 8, 8)
    -> (B, 32, 1, 1) -> (B, 6). The last kernel spans the whole 8 x 8 map, so every pixel of the
    image reaches the feature (a 6 x 6 kernel left the bottom and right 19 rows unseen). Small on
    purpose: on 2 CPU cores its backward pass is most of an update (bench/bench_sac.py)."""

    def __init__(self, img=80, norm="fixed", feat=FEAT):
        super().__init__()
        self.norm = norm
        self.conv = nn.Sequential(nn.Conv2d(1, 8, 4, stride=3), nn.ReLU(),
                                  nn.Conv2d(8, 16, 5, stride=3), nn.ReLU(),
                                  nn.Conv2d(16, 32, 8, stride=4), nn.ReLU(), nn.Flatten())
        with torch.no_grad():
            n = self.conv(torch.zeros(1, 1, img, img)).shape[1]
        self.fc = nn.Linear(n, feat)

    def forward(self, img):                  # img: (B, 80, 80) uint8
        return self.fc(self.conv(pixels(img, self.norm)))


class SpatialImageEncoder(nn.Module):
    """Where things are, not what they look like (ours, an option): two convolutions keep a map, a softmax over
    each channel's map gives its expected image coordinates, a keypoint (the spatial softmax of Levine et al.
    2016, with their learned temperature), and a linear layer maps the keypoints to the 6-d feature:
    (B, 1, 80, 80) -> (B, 8, 26, 26) -> (B, K, 12, 12) -> (B, 2K) x, y in [-1, 1] -> (B, 6). (A 24 x 24 map, the
    second convolution at stride 1, cost 1.4x the CNN's update time; at stride 2 it costs what the CNN does.)"""

    def __init__(self, img=80, norm="fixed", feat=FEAT, k=16):
        super().__init__()
        self.norm = norm
        self.conv = nn.Sequential(nn.Conv2d(1, 8, 4, stride=3), nn.ReLU(), nn.Conv2d(8, k, 3, stride=2))
        with torch.no_grad():
            h, w = self.conv(torch.zeros(1, 1, img, img)).shape[-2:]
        ys, xs = torch.meshgrid(torch.linspace(-1, 1, h), torch.linspace(-1, 1, w), indexing="ij")
        self.register_buffer("grid", torch.stack([xs.flatten(), ys.flatten()], 1))   # (h w, 2): each cell's x, y
        self.log_temp = nn.Parameter(torch.zeros(()))
        self.fc = nn.Linear(2 * k, feat)

    def keypoints(self, img):                # img: (B, 80, 80) uint8 -> (B, K, 2), x right and y down in [-1, 1]
        h = self.conv(pixels(img, self.norm)).flatten(2)                             # (B, K, h w)
        return torch.softmax(h / self.log_temp.exp(), -1) @ self.grid                 # each map's softmax, sums to 1

    def forward(self, img):
        return self.fc(self.keypoints(img).flatten(1))                                # (B, 2K) -> (B, 6)


IMAGE_ENCODERS = {"cnn": ImageEncoder, "spatial": SpatialImageEncoder}   # cnn: the paper's (Fig. 4)


class ImageDecoder(nn.Module):
    """The CNN's mirror (SAC-AE's decoder; ours, --aux-recon): features (B, n) -> (B, 32, 1, 1) -> (B, 16, 8, 8) ->
    (B, 8, 26, 26) -> (B, 1, 80, 80), the image as pixels() gives it."""

    def __init__(self, n_feat):
        super().__init__()
        self.fc = nn.Linear(n_feat, 32)
        self.deconv = nn.Sequential(nn.ReLU(), nn.ConvTranspose2d(32, 16, 8, stride=4), nn.ReLU(),
                                    nn.ConvTranspose2d(16, 8, 5, stride=3), nn.ReLU(),
                                    nn.ConvTranspose2d(8, 1, 4, stride=3, output_padding=1))

    def forward(self, z):
        return self.deconv(self.fc(z)[:, :, None, None])


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
                 image="cnn", image_norm="fixed", image_feat=FEAT):
        super().__init__()
        if image not in IMAGE_ENCODERS:
            raise ValueError(f"unknown image encoder {image!r} ({', '.join(IMAGE_ENCODERS)})")
        if image_norm not in IMAGE_NORMS:
            raise ValueError(f"unknown image normalisation {image_norm!r} ({', '.join(IMAGE_NORMS)})")
        if kind not in OBS_KINDS:
            raise ValueError(f"unknown observation kind {kind!r} ({', '.join(OBS_KINDS)})")
        self.kind, self.norm_kind, self.image_kind, self.image_norm, self.image_feat = kind, norm, image, image_norm, \
            image_feat
        self.register_buffer("pose_scale", torch.as_tensor(np.asarray(pose_scale), dtype=torch.float32))
        self.register_buffer("wrench_scale", torch.as_tensor(np.asarray(wrench_scale), dtype=torch.float32))
        if kind == "pt":
            self.now = mlp(12, 2 * FEAT, (64,))
        elif kind != "v":
            self.series = SeriesEncoder()
        # image_feat: the image's feature, the paper's 6 (wider: ours, issue 50's study)
        self.image = IMAGE_ENCODERS[image](img, image_norm, image_feat) if kind in ("ts-ptv", "v") else None
        # ts-ptk (keypoint RL): obs['keypoint'] (B, 4), the hole found in the image by a detector, in place of the CNN
        self.keypoint = mlp(4, FEAT, (32,)) if kind == "ts-ptk" else None
        self.out_dim = {"ts-ptv": 2 * FEAT + image_feat, "ts-ptk": 3 * FEAT, "v": image_feat}.get(kind, 2 * FEAT)
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
    """Two Q heads, each a 2 x 256 MLP on [fusion vector, action] (norm: LayerNorm after each hidden layer;
    dropout: DroQ's dropout)."""

    def __init__(self, n_feat, act_dim=6, norm=False, dropout=0.0):
        super().__init__()
        self.q1, self.q2 = (mlp(n_feat + act_dim, 1, norm=norm, dropout=dropout) for _ in range(2))

    def forward(self, z, a):
        za = torch.cat([z, a], -1)
        return self.q1(za).squeeze(-1), self.q2(za).squeeze(-1)


class QEnsemble(nn.Module):
    """REDQ's critics (Chen et al. 2021; ours, issue 50's study): n Q heads as TwinQ's; SAC's TD target takes the
    smaller of two drawn at random each update, the actor their mean."""

    def __init__(self, n_feat, act_dim=6, norm=False, dropout=0.0, n=10):
        super().__init__()
        self.heads = nn.ModuleList(mlp(n_feat + act_dim, 1, norm=norm, dropout=dropout) for _ in range(n))

    def forward(self, z, a):                   # -> n tensors (B,)
        za = torch.cat([z, a], -1)
        return tuple(h(za).squeeze(-1) for h in self.heads)


def actor_value(qs):
    """The critics' heads (B,) each -> what the actor maximises: twin Q's smaller, REDQ's mean over its heads."""
    return torch.min(*qs) if len(qs) == 2 else torch.stack(qs).mean(0)


@torch.no_grad()
def act(enc, actor, obs, deterministic=False, device="cpu"):
    """One env observation (unbatched dict of arrays) -> action (6,) in [-1, 1]."""
    o = {k: torch.as_tensor(v[None], device=device) for k, v in obs.items()}
    return actor(enc(o), deterministic, with_logp=False)[0][0].cpu().numpy()


# ---------------------------------------------------------------- replay buffer
class ReplayBuffer:
    """Ring buffer of transitions (o, a, r, o', terminated). Images are kept as uint8 (6.4 kB each);
    o' is stored next to o, which doubles the memory but keeps sampling a plain index. i: the next slot
    to write; n: the transitions held."""

    def __init__(self, capacity, obs_shapes, act_dim=6, nstep=1, gamma=0.95):
        self.capacity, self.n, self.i, self.nstep, self.gamma = capacity, 0, 0, nstep, gamma
        self.obs = {k: np.zeros((capacity, *s), np.uint8 if k == "image" else np.float32)
                    for k, s in obs_shapes.items()}
        self.next_obs = {k: np.zeros_like(v) for k, v in self.obs.items()}
        self.act = np.zeros((capacity, act_dim), np.float32)
        self.rew = np.zeros(capacity, np.float32)
        self.term = np.zeros(capacity, np.float32)
        self.disc = np.zeros(capacity, np.float32)      # the bootstrap's discount: gamma^(steps the return spans)

    def __len__(self):
        return self.n

    def add_episode(self, ep):
        """ep: {'obs': {k: (T + 1, ...)}, 'act': (T, 6), 'rew': (T,), 'term': (T,)}: the T + 1
        observations of one episode and its T transitions; obs keys the buffer was not built for are
        ignored."""
        T = len(ep["act"])
        j = (self.i + np.arange(T)) % self.capacity          # the slots this episode takes
        # n-step returns (nstep > 1; DrQ-v2's 3): r_t + gamma r_t+1 + ... over m = min(nstep, T - t) steps,
        # bootstrapped from o_t+m with gamma^m, unless the episode ended in success within them
        m = np.minimum(self.nstep, T - np.arange(T))
        rew = np.asarray(ep["rew"], np.float64)
        ret = np.array([np.sum(rew[t:t + m[t]] * self.gamma ** np.arange(m[t])) for t in range(T)])
        for k in self.obs:
            self.obs[k][j] = ep["obs"][k][:T]
            self.next_obs[k][j] = ep["obs"][k][np.arange(T) + m]
        self.act[j], self.term[j] = ep["act"], np.asarray(ep["term"])[np.arange(T) + m - 1]
        self.rew[j] = ep["rew"] if self.nstep == 1 else ret
        self.disc[j] = np.float32(self.gamma) ** m
        self.i = (self.i + T) % self.capacity
        self.n = min(self.n + T, self.capacity)

    def sample(self, batch, rng, jitter_s=0.0, shift=0, copies=1, positive=0):
        """A batch of transitions (o, a, r, o', terminated); with jitter_s, their images jittered (--augment);
        with shift, randomly shifted by up to that many pixels (--shift). copies: the batch `copies` times over,
        one after the other, each image augmented anew (DrQ's K = M, SAC(copies=...) averages them). positive:
        also o['image_pos'], o's image shifted anew by up to this many pixels (CURL's positive)."""
        idx = np.tile(rng.integers(0, self.n, batch), copies)
        o, o2 = ({k: v[idx] for k, v in d.items()} for d in (self.obs, self.next_obs))
        if positive and "image" in o:
            o["image_pos"] = random_shift(o["image"], rng, positive)
        if jitter_s and "image" in o:           # o and o' jittered independently, as DrQ does
            o["image"], o2["image"] = jitter(o["image"], rng, jitter_s), jitter(o2["image"], rng, jitter_s)
        if shift and "image" in o:
            o["image"], o2["image"] = random_shift(o["image"], rng, shift), random_shift(o2["image"], rng, shift)
        return o, self.act[idx], self.rew[idx], o2, self.term[idx], self.disc[idx]


def random_shift(images, rng, pad):
    """DrQ's augmentation (Kostrikov et al. 2020): each gray image (B, H, W) uint8 padded by `pad` pixels,
    repeating its edge, and cropped back to (H, W) at a random offset: shifted by up to +-pad pixels."""
    B, H, W = images.shape
    padded = np.pad(images, ((0, 0), (pad, pad), (pad, pad)), mode="edge")
    dy, dx = rng.integers(0, 2 * pad + 1, (2, B))
    rows = (dy[:, None] + np.arange(H))[:, :, None]                 # (B, H, 1)
    cols = (dx[:, None] + np.arange(W))[:, None, :]                 # (B, 1, W)
    return padded[np.arange(B)[:, None, None], rows, cols]


def jitter(images, rng, s):
    """Photometric augmentation of gray images (B, H, W) uint8: each image's brightness, then its contrast about
    its mean, scaled by U(1 - s, 1 + s), as the brightness and contrast of RAD's colour jitter (Laskin et al.
    2020). Not the paper's method, which claims to need none: tacrl's --augment (README difference 17)."""
    x = images.astype(np.float32) * rng.uniform(1 - s, 1 + s, (len(images), 1, 1)).astype(np.float32)
    m = x.mean(axis=(1, 2), keepdims=True)
    x = (x - m) * rng.uniform(1 - s, 1 + s, (len(images), 1, 1)).astype(np.float32) + m
    return np.clip(np.rint(x), 0, 255).astype(np.uint8)


# ---------------------------------------------------------------- the CPU: two cores in one update
def keep_freed_memory():
    """Let glibc's malloc keep what it frees (M_MMAP_THRESHOLD 32 MB, M_TRIM_THRESHOLD 1 GB) instead of handing
    blocks back to the kernel: otherwise every update's LSTM and convolution buffers (a few MB) come back as fresh
    pages that fault in one by one, and the LSTM's forward and backward took over twice as long. A run then holds
    its largest working set. Process-wide; a no-op where libc is not glibc."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-3, 32 << 20)          # M_MMAP_THRESHOLD: blocks up to 32 MB from the heap, not mmap
        libc.mallopt(-1, 1 << 30)           # M_TRIM_THRESHOLD: keep up to 1 GB of free heap
    except (OSError, AttributeError):
        pass


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


class SAC:
    """SAC (Haarnoja et al. 2018) with twin Q, target networks (Polyak), automatic temperature
    (target entropy -|A| unless given).

    Critics: with state_dim 0, the paper's: twin Q on the multimodal encoder, which the actor reads
    with the gradient stopped (as in SAC-AE and DrQ), so the encoder learns from the TD error only
    and each update encodes o and o' once each (o' by the target encoder, also for a'). With
    state_dim > 0, privileged (an asymmetric actor-critic, Pinto et al. 2018; not in the paper):
    they read StateEncoder(obs), which includes obs['state'] (state_dim,), and the actor has a
    multimodal encoder of its own, trained through the actor loss. The critics then need not
    learn to see the hole before they can say which way it lies.

    On the CPU each multimodal encoder reads a batch as its two halves (encode, in_halves): with threads=2 the
    second half runs on a helper thread, forward and backward, which puts the LSTM and the CNN, most of an update,
    on two cores. Call torch.set_num_threads(1) first (as tacrl.use_cpu does), so that every op runs on the thread
    that calls it: the numbers are then the same with threads=1 or 2, and a run repeats on any machine.
    """

    def __init__(self, obs_kind="ts-ptv", pose_scale=np.ones(6), wrench_scale=np.ones(6), act_dim=6,
                 lr=3e-4, gamma=0.95, tau=0.005, init_alpha=0.1, target_entropy=None, state_dim=0, device="cpu",
                 extra_dim=0, target_encoder=True, norm="joint", own_actor_encoder=False, aux_reward=0.0,
                 aux_state=0.0, image="cnn", image_norm="fixed", q_norm=False, threads=1, q_dropout=0.0, n_q=2,
                 aux_wrench=0.0, image_feat=FEAT, copies=1, aux_recon=0.0, enc_lr=None, aux_curl=0.0):
        self.device, self.gamma, self.tau = torch.device(device), gamma, tau
        # copies K: a batch holds K augmented copies of each transition (ReplayBuffer.sample); the TD target is their
        # mean, the critics' loss is over all K and the actor reads the first: DrQ's K = M (Kostrikov et al. 2020;
        # ours, issue 50's study)
        self.copies = copies
        self.helper = Helper(threads)        # threads=2: each multimodal encoder's batch as two halves, side by side
        # the paper's critics lend the actor their encoder, unless it has one of its own (as it always has with
        # privileged critics), trained through the actor loss
        self.shared = not state_dim and not own_actor_encoder
        self.extra_dim, self.target_encoder = extra_dim, target_encoder
        enc = lambda: Encoder(obs_kind, pose_scale, wrench_scale, norm=norm, image=image,  # noqa: E731
                              image_norm=image_norm, image_feat=image_feat).to(self.device)
        self.enc = StateEncoder(state_dim, pose_scale, wrench_scale).to(self.device) if state_dim else enc()
        n_in = self.enc.out_dim + extra_dim
        self.q = (TwinQ(n_in, act_dim, norm=q_norm, dropout=q_dropout) if n_q == 2 else
                  QEnsemble(n_in, act_dim, norm=q_norm, dropout=q_dropout, n=n_q)).to(self.device)
        self.enc_targ, self.q_targ = copy.deepcopy(self.enc), copy.deepcopy(self.q)
        for p in list(self.enc_targ.parameters()) + list(self.q_targ.parameters()):
            p.requires_grad_(False)
        self.actor_enc = self.enc if self.shared else enc()      # what the actor reads: never obs['state']
        self.actor = Actor(self.actor_enc.out_dim, act_dim).to(self.device)
        self.log_alpha = torch.tensor(np.log(init_alpha), dtype=torch.float32, device=self.device,
                                      requires_grad=True)
        self.target_entropy = -float(act_dim) if target_entropy is None else float(target_entropy)
        self._online_params = list(self.enc.parameters()) + list(self.q.parameters())
        self._targ_params = list(self.enc_targ.parameters()) + list(self.q_targ.parameters())
        # fused Adam: one kernel a step for all parameters; the same Adam to rounding (1.5e-7 apart after 10
        # updates), 1.06x the updates/s of foreach=True here (bench/bench_update.py)
        # aux_reward w: a head on the critics' input and the action predicts the reward, its squared error (x w)
        # added to the critics' loss, so that their encoder gets a gradient of lower variance than the TD error's
        # (UNREAL's reward prediction, Jaderberg et al. 2017; the reward is the environment's, no other label)
        self.aux_reward = aux_reward
        self.r_head = mlp(self.enc.out_dim + extra_dim + act_dim, 1, (256,)).to(self.device) if aux_reward else None
        # aux_state w (the paper's critics): a linear head on their encoder's features predicts obs['state'][:4],
        # what training knows of the state (the offset from the true goal; the label only, never an input), its
        # squared error (x w) added to their loss: an auxiliary task on privileged information, as Mirowski et
        # al. (2017) predict depth; the critics read the paper's observation alone
        self.aux_state = aux_state
        self.s_head = nn.Linear(self.enc.out_dim, 4).to(self.device) if aux_state else None
        # aux_wrench w: a head on the critics' input and the action predicts the next wrench reading, which the agent
        # observes (a forward model of touch, ours, issue 50's study: no label that training alone knows)
        self.aux_wrench = aux_wrench
        self.w_head = mlp(self.enc.out_dim + extra_dim + act_dim, 6, (256,)).to(self.device) if aux_wrench else None
        # aux_recon w: a decoder rebuilds o's image from the critics' features, its squared error (x w) added to their
        # loss (SAC-AE, Yarats et al. 2019; ours, issue 50's study: the image is observed, no privileged label)
        self.aux_recon = aux_recon
        self.decoder = ImageDecoder(self.enc.out_dim).to(self.device) if aux_recon else None
        # aux_curl w: CURL's contrastive loss (Srinivas et al. 2020; ours, issue 50's study): the critics' features of o
        # (the anchor) score the target encoder's of the same o shifted anew (o['image_pos'], the positive) above
        # those of the batch's other observations, through a learned bilinear W; its cross-entropy (x w) is added
        self.aux_curl = aux_curl
        self.curl_w = nn.Linear(self.enc.out_dim, self.enc.out_dim, bias=False).to(self.device) if aux_curl else None
        heads = [h for h in (self.r_head, self.s_head, self.w_head, self.decoder, self.curl_w) if h is not None]
        rest = list(self.q.parameters()) + [p for h in heads for p in h.parameters()]
        # enc_lr: the critics' encoder's own Adam step size (ours, issue 50's study; None: lr, as the rest)
        groups = [{"params": list(self.enc.parameters()) + rest}] if enc_lr is None else \
            [{"params": list(self.enc.parameters()), "lr": enc_lr}, {"params": rest}]
        self.q_opt = torch.optim.Adam(groups, lr=lr, fused=True)
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
        """One gradient step on a batch from ReplayBuffer.sample, (o, a, r, o', terminated[, discount]) (without
        the discount: gamma, one-step returns); returns the losses."""
        o, a, r, o2, term, *disc = batch
        disc = torch.as_tensor(disc[0], device=self.device) if disc else self.gamma
        o, o2 = ({k: torch.as_tensor(v, device=self.device) for k, v in x.items()} for x in (o, o2))
        a, r, term = (torch.as_tensor(x, device=self.device) for x in (a, r, term))
        alpha = self.log_alpha.exp().detach()
        # critics: regress Q(o, a) on the TD target y (td_target)
        with torch.no_grad():
            # (B, n_feat): o' encoded once, by the target encoder, or (target_encoder False) by the online one
            # without gradient, as DrQ-v2 does (Yarats et al. 2021), so that a' follows the actor's encoder of now
            z2 = self.encode(self.enc_targ if self.target_encoder else self.enc, o2)
            a2, logp2 = self.actor(z2 if self.shared else self.encode(self.actor_enc, o2))
            q_t = self.q_targ(self.critic_input(z2, o2), a2)
            if len(q_t) > 2:                                  # REDQ: the smaller of two heads drawn at random
                q_t = [q_t[i] for i in torch.randperm(len(q_t))[:2].tolist()]
            y = td_target(r, term, torch.min(*q_t), logp2, alpha, disc)
            if self.copies > 1:                               # DrQ: the target averaged over the copies of o'
                y = y.view(self.copies, -1).mean(0).repeat(self.copies)
        z = self.encode(self.enc, o)
        zc = self.critic_input(z, o)
        q_loss = sum(F.mse_loss(q, y) for q in self.q(zc, a))
        za = torch.cat([zc, a], 1) if self.aux_reward or self.aux_wrench else None     # the reward and wrench heads'
        aux = 0.0
        if self.aux_reward:
            aux = self.aux_reward * F.mse_loss(self.r_head(za).squeeze(-1), r)
        if self.aux_state:
            aux = aux + self.aux_state * F.mse_loss(self.s_head(z), o["state"][:, :4])
        if self.aux_recon:
            aux = aux + self.aux_recon * F.mse_loss(self.decoder(z), pixels(o["image"]))
        if self.aux_curl:
            with torch.no_grad():
                z_pos = self.enc_targ({**o, "image": o["image_pos"]})                      # (B, n_feat)
            logits = self.curl_w(z) @ z_pos.T                                              # (B, B): anchor i, key j
            aux = aux + self.aux_curl * F.cross_entropy(logits - logits.max(1, keepdim=True).values,
                                                         torch.arange(len(z), device=self.device))
        if self.aux_wrench:
            w_next = o2["wrench_hist"][:, -1] / self.enc.wrench_scale
            aux = aux + self.aux_wrench * F.mse_loss(self.w_head(za), w_next)
        self.q_opt.zero_grad(set_to_none=True)
        (q_loss + aux).backward()
        self.q_opt.step()

        # actor: maximise min Q(o, pi(o)) - alpha log pi, the critics only read
        if self.copies > 1:                                   # DrQ's actor reads the first copy
            n = len(a) // self.copies
            z, o = z[:n], {k: v[:n] for k, v in o.items()}
        z_pi = z.detach() if self.shared else self.encode(self.actor_enc, o)
        a_pi, logp = self.actor(z_pi)
        for p in self.q.parameters():
            p.requires_grad_(False)
        q_pi = self.q(self.critic_input(z.detach(), o), a_pi)
        for p in self.q.parameters():
            p.requires_grad_(True)
        pi_loss = (alpha * logp - actor_value(q_pi)).mean()
        self.pi_opt.zero_grad(set_to_none=True)
        pi_loss.backward()
        self.pi_opt.step()

        # temperature: towards the target entropy
        alpha_loss = -(self.log_alpha * (logp.detach() + self.target_entropy)).mean()
        self.alpha_opt.zero_grad(set_to_none=True)
        alpha_loss.backward()
        self.alpha_opt.step()

        with torch.no_grad():   # Polyak averaging of the targets: p_targ <- (1 - tau) p_targ + tau p
            for p_targ, p in zip(self._targ_params, self._online_params):
                p_targ.lerp_(p, self.tau)
        return {"q_loss": q_loss.item(), "pi_loss": pi_loss.item(), "alpha": alpha.item(),
                "entropy": -logp.mean().item()}

    def reset_heads(self):
        """Nikishin et al. (2022)'s resets against primacy bias, as they reset DrQ (ours, issue 50's study): the
        actor's and the critics' MLP heads (and their targets) drawn anew and their Adam moments forgotten; the
        encoder, the temperature and the replay keep what they hold."""
        for m in list(self.q.modules()) + list(self.actor.modules()):
            if isinstance(m, (nn.Linear, nn.LayerNorm)):
                m.reset_parameters()
        self.q_targ.load_state_dict(self.q.state_dict())
        for opt, params in ((self.q_opt, self.q.parameters()), (self.pi_opt, self.actor.parameters())):
            for p in params:
                opt.state.pop(p, None)

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
        m = {"enc": self.enc, "q": self.q, "enc_targ": self.enc_targ, "q_targ": self.q_targ, "actor": self.actor,
             "q_opt": self.q_opt, "pi_opt": self.pi_opt, "alpha_opt": self.alpha_opt}
        if not self.shared:
            m["actor_enc"] = self.actor_enc
        if self.r_head is not None:
            m["r_head"] = self.r_head
        if self.s_head is not None:
            m["s_head"] = self.s_head
        if self.w_head is not None:
            m["w_head"] = self.w_head
        if self.decoder is not None:
            m["decoder"] = self.decoder
        if self.curl_w is not None:
            m["curl_w"] = self.curl_w
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


# ---------------------------------------------------------------- a trained policy, as evaluation loads it
POLICY_FORMAT = "tacrl-policy-2"


def save_atomic(obj, path):
    """torch.save to path.tmp, then rename: an interrupt leaves the old file or the new one."""
    torch.save(obj, path + ".tmp")
    os.replace(path + ".tmp", path)


def load_file(path, device="cpu"):
    """torch.load of a file this module saved: tensors and plain values only (weights_only), and quietly,
    since torch warns about a foreign pickle before it refuses it; the caller reports what is wrong."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return torch.load(path, map_location=device, weights_only=True)
        except pickle.UnpicklingError:
            raise ValueError("not a file of tensors that torch loads safely (weights_only)") from None


def save_policy(path, sac, meta):
    """policy.pt: the actor and the encoder it reads (the critics stay behind), and meta, a dict of
    plain values that evaluation must know of training ('obs' among them: the encoder's kind)."""
    save_atomic({"format": POLICY_FORMAT, **meta, "norm": sac.actor_enc.norm_kind,
                 "image_encoder": sac.actor_enc.image_kind, "image_norm": sac.actor_enc.image_norm,
                 "image_feat": sac.actor_enc.image_feat,
                 "encoder": sac.actor_enc.state_dict(),
                 "actor": sac.actor.state_dict()}, path)


class TrainedPolicy:
    """A policy.pt's contents (torch.load) as act(obs) -> action: the deterministic actor (the
    Gaussian's mean). .meta holds what save_policy was given."""

    def __init__(self, d, device="cpu"):
        if not isinstance(d, dict) or d.get("format") != POLICY_FORMAT:
            raise ValueError("not a tacrl policy file")
        self.meta = {k: v for k, v in d.items() if k not in ("format", "encoder", "actor")}
        self.device = device
        # (files before 'norm', 'image_encoder', 'image_norm' and 'image_feat': joint, cnn, fixed, 6)
        self.encoder = Encoder(d["obs"], norm=d.get("norm", "joint"), image=d.get("image_encoder", "cnn"),
                               image_norm=d.get("image_norm", "fixed"), image_feat=d.get("image_feat", FEAT))
        self.encoder.to(device).eval()
        self.encoder.load_state_dict(d["encoder"])
        self.actor = Actor(self.encoder.out_dim).to(device).eval()
        self.actor.load_state_dict(d["actor"])

    def __call__(self, obs):
        return act(self.encoder, self.actor, obs, deterministic=True, device=self.device)
