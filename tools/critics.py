"""critics.py: what a run's critics learned (issue 50), written to <run dir>/critics.json, which the archive
keeps and `report.py --compare` shows:

    python tools/critics.py "runs/critics/*"        # each run with a policy.pt; Q needs its ckpt.pt too

Both on held-out seeds at the run's final error range (apart from training's, validation's and evaluation's):
- A linear probe: do the features say where the hole is? The env is reset `resets` times; the first
  observation's features (those the critics read: the fusion vector of the encoder they share with the
  actor) are fitted by ridge regression to X - X_g (x, y, z, yaw) on half of the resets and scored (R^2) on
  the other half: 1 when the features hold the offset linearly, 0 when they say nothing of it. A probe,
  never a loss: nothing is trained. The same encoder untrained (the run's first draw) is probed beside it.
  Privileged critics read X - X_g itself; their run probes the actor's encoder instead, for comparison.
- Q against Monte-Carlo returns: `episodes` episodes, the policy acting as it trained (actions drawn from the
  Gaussian); each transition's Q(o, a) (the smaller twin, or the ensemble's mean: what the actor maximises)
  against the soft return that followed it, r_t + sum_k gamma^k (r_t+k - alpha log pi(a_t+k | o_t+k)),
  which Q estimates. Only transitions whose return is known: those of an episode that ended in success, and
  those of a timed-out one at least TAIL steps before the cut (gamma^TAIL of the unknown rest left out).
  Needs the critics, which only ckpt.pt keeps (a run dir, not the archive).
"""
import copy
import json
import os
import signal
import sys

if __name__ == "__main__":     # Ctrl-C while torch and pybullet load: one line and exit 130
    signal.signal(signal.SIGINT, lambda *_: (sys.stderr.write("\ncritics: interrupted\n"), os._exit(130)))

import numpy as np  # noqa: E402
import torch  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the core modules, one folder up
import cli  # noqa: E402
import command  # noqa: E402
import evaluate  # noqa: E402
import runs  # noqa: E402
import tacrl  # noqa: E402
from cli import ArgError  # noqa: E402

PROBE_SEED = 3000            # episode seeds from evaluate.episode_seed(PROBE_SEED + the run's seed, k)
TAIL = 60                    # steps before a time-out a transition must be: 0.95^60 = 0.05 of the return unknown
OFFSET = ("x", "y", "z", "yaw")     # X - X_g as critic_state scales it: x, y / 5 mm, z / 25 mm, yaw / 0.025 rad


def soft_returns(r, logp_next, gamma, alpha):
    """(T,) rewards and log pi of the next step's action (T,; the last unused) -> (T,) soft returns G_t = r_t +
    gamma (G_t+1 - alpha logp_t+1), nothing after the last step (exact after a success; a time-out's tail is
    left out by the caller's TAIL)."""
    g, out = 0.0, np.zeros(len(r))
    for t in reversed(range(len(r))):
        g = r[t] + (gamma * (g - alpha * logp_next[t]) if t < len(r) - 1 else 0.0)
        out[t] = g
    return out


def ridge_r2(x_fit, y_fit, x_test, y_test, lam=1e-2):
    """R^2 per target column of a ridge regression (standardised features, a bias) fitted on one set, scored on the
    other."""
    mu, sd = x_fit.mean(0), x_fit.std(0) + 1e-8
    a = (x_fit - mu) / sd
    w = np.linalg.solve(a.T @ a + lam * len(a) * np.eye(a.shape[1]), a.T @ (y_fit - y_fit.mean(0)))
    pred = (x_test - mu) / sd @ w + y_fit.mean(0)                  # (the bias, the fit's mean, is not shrunk)
    return 1 - ((pred - y_test) ** 2).sum(0) / ((y_test - y_test.mean(0)) ** 2).sum(0)


def diagnose(run_dir, resets=200, episodes=20, log=print):
    """critics.json's contents for one run dir."""
    try:
        cfg = tacrl.read_config(run_dir)
    except ValueError as e:                          # a run of the critics study: its tag's critics.py reads it
        raise ArgError(f"{run_dir}: {e}")
    pi = runs.load_policy(runs.load_run(run_dir))
    torch.manual_seed(cfg.seed)                       # the run's networks as its training drew them, before it
    sac = tacrl.make_sac(cfg, device="cpu")
    enc0 = copy.deepcopy(sac.actor_enc)              # the probe's reference: the same encoder untrained
    ckpt = os.path.join(run_dir, "ckpt.pt")
    has_q = os.path.exists(ckpt)
    if has_q:
        sac.load_state_dict(torch.load(ckpt, map_location="cpu", weights_only=False)["sac"])
        sac.q.eval()
    else:                                             # the actor and its encoder alone, as policy.pt keeps them
        sac.actor_enc.load_state_dict(pi.encoder.state_dict())
        sac.actor.load_state_dict(pi.actor.state_dict())
    seed = lambda k: evaluate.episode_seed(PROBE_SEED + cfg.seed, k)     # noqa: E731
    with evaluate.eval_env(cfg.task, pi, cfg.context, cfg.roi, cfg.clearance_mm, e_r_mm=cfg.error_mm) as env:
        obs, offsets = [], []
        for k in range(resets):
            o, info = env.reset(seed=seed(k))
            obs.append(o)
            offsets.append(tacrl.critic_state(info)[:4])
        o = {key: torch.as_tensor(np.stack([x[key] for x in obs])) for key in obs[0]}
        with torch.no_grad():
            feats = {"r2": sac.actor_enc(o).numpy(), "r2_untrained": enc0(o).numpy()}
        y, h = np.array(offsets), resets // 2
        probe = {k: dict(zip(OFFSET, np.round(ridge_r2(f[:h], y[:h], f[h:], y[h:]), 3).tolist()))
                 for k, f in feats.items()}
        log(f"  {os.path.basename(run_dir)}: probe {probe}")
        q_mc = q_against_returns(sac, env, cfg, [seed(resets + k) for k in range(episodes)], log) if has_q else None
    return {"resets": resets, "episodes": episodes, "error_mm": cfg.error_mm, "seed": PROBE_SEED + cfg.seed,
            "probe": {"features": "the actor's encoder" if cfg.critic == "privileged" else "the critics' encoder",
                      **probe}, "q_vs_mc": q_mc}


def q_against_returns(sac, env, cfg, seeds, log):
    """Q(o, a) against the soft Monte-Carlo return on the episodes of these seeds (the docstring's second part)."""
    torch.manual_seed(PROBE_SEED + cfg.seed)
    logps, pairs = [], []

    def act(obs):                                     # as in training: drawn from the Gaussian, with its log pi
        with torch.no_grad():
            a, logp = sac.actor(sac.actor_enc({k: torch.as_tensor(v[None]) for k, v in obs.items()}))
        logps.append(logp.item())
        return a[0].numpy()
    for k, s in enumerate(seeds):
        logps.clear()
        ep = tacrl.rollout(env, act, seed=s)
        T, term = len(ep["act"]), bool(ep["term"][-1])
        o = {key: torch.as_tensor(v[:T]) for key, v in ep["obs"].items()}
        with torch.no_grad():
            qs = sac.q(sac.critic_input(sac.enc(o), o), torch.as_tensor(ep["act"]))
        q = torch.min(*qs).numpy()
        g = soft_returns(ep["rew"], np.append(logps[1:], 0.0), cfg.gamma, sac.log_alpha.exp().item())
        known = np.arange(T) < (T if term else T - TAIL)
        pairs += list(zip(q[known], g[known]))
        log(f"  episode {k + 1}/{len(seeds)} success {int(term)} steps {T}")
    if not pairs:
        return None
    q, g = np.array(pairs).T
    rnd = lambda x, n=2: round(float(x), n)          # noqa: E731
    return {"transitions": len(q), "q_mean": rnd(q.mean()), "mc_mean": rnd(g.mean()), "bias": rnd((q - g).mean()),
            "rmse": rnd(np.sqrt(((q - g) ** 2).mean())), "corr": rnd(np.corrcoef(q, g)[0, 1], 3)}


def main(argv=None):
    ap = cli.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", help="comma-separated glob patterns of run directories (with policy.pt)")
    ap.add_argument("--resets", type=int, default=200, help="the probe's held-out resets a run (default: 200)")
    ap.add_argument("--episodes", type=int, default=20, help="held-out episodes a run for Q (default: 20)")
    a = ap.parse_args(argv)
    if a.resets < 4 or a.episodes < 1:
        raise ArgError(f"--resets must be at least 4 (the probe fits on half, scores on the other) and --episodes at "
                       f"least 1, not {a.resets} and {a.episodes}")
    dirs = [d for d in runs.match_runs(a.runs) if os.path.exists(os.path.join(d, "policy.pt"))]
    if not dirs:
        raise ArgError(f"{a.runs!r}: no run with a policy.pt")
    command.use_cpu()
    for d in dirs:
        out = diagnose(d, a.resets, a.episodes, log=lambda *_: None)
        cli.check_dir_writable(d, "the run dir")
        with open(os.path.join(d, "critics.json"), "w") as f:
            json.dump(out, f, indent=2)
        print(f"{d}: {json.dumps(out['q_vs_mc'])}; probe R^2 {out['probe']['r2']} (untrained: "
              f"{out['probe']['r2_untrained']})", flush=True)


if __name__ == "__main__":
    sys.exit(cli.command("critics", main))
