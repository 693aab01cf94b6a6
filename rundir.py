"""rundir.py: what a training run's directory holds, read and written here and nowhere else.

    config.json     the run's flags (tacrl.Config), written when it starts
    ckpt.pt         after every episode: networks and optimisers, curriculum, stop rule, random states,
                    where the replay ring stands (a kill loses at most the episode in flight)
    replay/         one ep_NNNNNN.npz an episode the ring still holds (plain arrays, no pickle)
    metrics.csv     one row an episode (METRICS); tb/ the same for TensorBoard, with --track
    train.log       the console, where tools/sweep.py started the run
    policy.pt, curves.png, eval.json, eval-*.json   what the finished run's policy made; extended, a run
                    sets them aside as NAME-epN.EXT (set_aside) and makes them anew

A run directory that cannot be continued as it is raises RunError, naming what is wrong.
"""
import collections
import copy
import csv
import io
import json
import os
import pickle
import re
import time
import warnings

import numpy as np
import torch


LOG = "train.log"
METRICS = ["episode", "return", "success", "sr15", "e_r_mm", "ex_r_mm", "delta", "steps", "total_steps", "updates",
           "q_loss", "pi_loss", "alpha", "entropy", "env_s", "update_s", "elapsed_s"]
DIGITS = {"delta": 4}           # metrics.csv's decimals where not 3 (losses: 5, times: 1-2)
TB_GROUPS = {"charts": ("return", "success", "sr15", "e_r_mm", "ex_r_mm", "delta", "steps", "total_steps", "updates"),
             "losses": ("q_loss", "pi_loss", "alpha", "entropy"), "time": ("env_s", "update_s", "elapsed_s")}
TB_IMAGE_EVERY = 10          # episodes between the task-attention images sent to TensorBoard
EVAL_LIKE = 15               # the last episodes whose env time the ETA takes for the evaluation's


def save_atomic(obj, path):
    """torch.save to path.tmp, then rename: an interrupt, or a write that fails (a full disk), leaves the old file
    whole. Serialized in memory first and written as bytes, so that a failed write is an OSError with its errno
    (torch's own file writer turns one into a RuntimeError that names none)."""
    buf = io.BytesIO()
    torch.save(obj, buf)
    replace_atomic(path, lambda f: f.write(buf.getbuffer()))


def replace_atomic(path, write, mode="wb", **open_kw):
    """write(f) to path.tmp, then rename it to path; where writing fails, path.tmp is removed and path stays as it
    was (the last complete file)."""
    tmp = path + ".tmp"
    try:
        with open(tmp, mode, **open_kw) as f:
            write(f)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def load_file(path, device="cpu"):
    """torch.load of a file save_atomic saved: tensors and plain values only (weights_only), and quietly,
    since torch warns about a foreign pickle before it refuses it; the caller reports what is wrong."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return torch.load(path, map_location=device, weights_only=True)
        except pickle.UnpicklingError:
            raise ValueError("not a file of tensors that torch loads safely (weights_only)") from None


class RunError(ValueError):
    """A run directory that cannot be continued as it is."""


class Busy(RunError):
    """A run directory another process is writing."""


BUSY = "another process is writing this run directory; wait for it to end"


def lock(run_dir):
    """Take the run dir's lock (flock on the directory itself: no file is written) until the returned descriptor is
    closed; Busy where another process holds it. The kernel frees it when its holder ends however it ends, so no
    stale lock is ever left to clear by hand."""
    import fcntl
    os.makedirs(run_dir, exist_ok=True)
    fd = os.open(run_dir, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise Busy(BUSY)
    return fd


def busy(run_dir):
    """Busy's message where another process holds the run dir's lock now, else None; it changes nothing."""
    if not os.path.isdir(run_dir):
        return None
    try:
        os.close(lock(run_dir))
    except Busy as e:
        return str(e)
    return None


# ---------------------------------------------------------------- config.json and metrics.csv
def read_config(run_dir):
    """config.json as a dict; OSError, or ValueError where it is not a JSON object."""
    with open(os.path.join(run_dir, "config.json")) as f:
        d = json.load(f)
    if not isinstance(d, dict):
        raise ValueError("not a JSON object")
    return d


def write_config(run_dir, d):
    write_json(os.path.join(run_dir, "config.json"), d)


def write_json(path, d):
    """A JSON file written whole or not at all (replace_atomic)."""
    replace_atomic(path, lambda f: json.dump(d, f, indent=2), mode="w")


def read_log(path, columns, upto):
    """The first `upto` rows of a CSV log of numbered episodes (none for upto 0); ValueError where the log
    has not got them all, in these columns."""
    if not upto:
        return []
    with open(path, newline="") as f:
        reader = csv.DictReader(f)         # (a row cut short by a full disk lacks fields: it is past the checkpoint)
        rows = [r for r in reader if None not in r.values() and int(r["episode"]) <= upto]
    if reader.fieldnames != columns or [int(r["episode"]) for r in rows] != list(range(1, upto + 1)):
        raise ValueError(f"{os.path.basename(path)}'s rows are not episodes 1-{upto} of this version's columns")
    return rows


def write_log(path, columns, rows):
    """A CSV log written whole (replace_atomic): a resumed run's metrics.csv, as its checkpoint has it."""
    def write(f):
        csv.DictWriter(f, columns).writeheader()
        csv.DictWriter(f, columns).writerows(rows)
    replace_atomic(path, write, mode="w", newline="")


def read_metrics(run_dir):
    """metrics.csv as {column: [values]}, numbers as floats; a last row cut short (a full disk) is no row."""
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        rows = [r for r in csv.DictReader(f) if None not in r.values()]
    return {k: [float(r[k]) for r in rows] for k in (rows[0] if rows else METRICS)}


# ---------------------------------------------------------------- a finished run's evaluations
def is_evaluation(name):
    """A run dir's file that holds an evaluation of its policy: eval.json and every cached eval*.json."""
    return name.startswith("eval") and name.endswith(".json")


def set_aside(run_dir, episode):
    """Rename what a finished run's policy made (policy.pt, curves.png, eval.json and every evaluation cached
    as eval*.json) to NAME-ep<episode>.EXT when the run is extended, so that its new policy is evaluated
    anew; files set aside before stay as they are."""
    for name in sorted(os.listdir(run_dir)):
        stem, ext = os.path.splitext(name)
        if name in ("policy.pt", "curves.png") or (is_evaluation(name) and not re.search(r"-ep\d+$", stem)):
            os.replace(os.path.join(run_dir, name), os.path.join(run_dir, f"{stem}-ep{episode}{ext}"))


def set_aside_at(run_dir):
    """The episodes at which set_aside kept a run's earlier policies (its eval-epN.json), oldest first."""
    return sorted(int(m[1]) for m in (re.fullmatch(r"eval-ep(\d+)\.json", f) for f in os.listdir(run_dir)) if m)


CURVES = {"return": "cumulative reward (mean of 15)", "sr15": "success rate (last 15)",
          "e_r_mm": "guidance error range E_r (mm)", "ex_r_mm": "exploration range Ex_r (mm)"}


def smooth(x, k=15):
    """Moving average over k episodes (shorter at the start), as the paper smooths its curves."""
    c = np.cumsum(np.insert(np.asarray(x, float), 0, 0.0))
    n = np.minimum(np.arange(1, len(x) + 1), k)
    return (c[1:] - c[np.arange(1, len(x) + 1) - n]) / n


def plot_curves(run_dir, title=""):
    """The run's curves.png (Fig. 10 style): cumulative reward, success rate over the last 15, E_r and Ex_r
    against episode, from its metrics.csv. matplotlib is imported here: training needs it only at its end."""
    import matplotlib
    matplotlib.use("Agg")                    # files only, no display
    import matplotlib.pyplot as plt
    m = {k: np.array(v) for k, v in read_metrics(run_dir).items()}
    fig, axs = plt.subplots(1, len(CURVES), figsize=(16, 3.4))
    for ax, key in zip(axs, CURVES):
        if key == "return":
            ax.plot(m["episode"], m[key], lw=0.7, alpha=0.5, label="episode")
            ax.plot(m["episode"], smooth(m[key]), lw=1.5, label="mean of 15")
            ax.legend(fontsize=8)
        else:
            ax.plot(m["episode"], m[key])
        if key == "sr15":
            ax.set_ylim(-0.05, 1.05)
        ax.set_xlabel("episode")
        ax.set_ylabel(CURVES[key])
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.subplots_adjust(left=0.045, right=0.99, bottom=0.15, top=0.87, wspace=0.28)   # (tight_layout: a 2nd draw)
    fig.savefig(os.path.join(run_dir, "curves.png"), dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------- the replay ring on disk
class ReplayFiles:
    """The replay buffer's episodes on disk, one replay/ep_NNNNNN.npz each (plain arrays: np.load needs no
    pickle), so that a run stopped between episodes restarts with the same buffer. A checkpoint keeps
    `state(buf)`: the files the ring still holds and where it stands; `prune()`, after the checkpoint is
    saved, deletes the files it no longer holds; `restore(buf, state)` refills a new buffer, every
    transition in the slot it had. The buffer itself (policy.ReplayBuffer) knows nothing of files."""

    def __init__(self, directory, capacity, keys):
        self.directory, self.capacity, self.keys = directory, capacity, tuple(keys)     # keys: the obs the ring keeps
        self.files = collections.deque()       # [file name, transitions] of the episodes on disk, oldest first

    def add(self, ep, number):
        name = f"ep_{number:06d}.npz"
        path = os.path.join(self.directory, name)
        os.makedirs(self.directory, exist_ok=True)
        np.savez(path + ".tmp.npz", act=ep["act"], rew=ep["rew"], term=ep["term"],
                 **{"obs_" + k: ep["obs"][k] for k in self.keys})
        os.replace(path + ".tmp.npz", path)              # an interrupt leaves no half-written file
        self.files.append([name, len(ep["act"])])

    def _unheld(self):
        """How many of the oldest files the ring no longer needs: the newer ones alone fill it."""
        held, k = sum(t for _, t in self.files), 0
        while k < len(self.files) and held - self.files[k][1] >= self.capacity:
            held -= self.files[k][1]
            k += 1
        return k

    def state(self, buf):
        return {"i": buf.i, "n": buf.n, "files": [list(f) for f in list(self.files)[self._unheld():]]}

    def prune(self):
        for _ in range(self._unheld()):
            os.remove(os.path.join(self.directory, self.files.popleft()[0]))

    def restore(self, buf, state):
        """Refill the empty ring `buf` from the files `state` names, each transition in its slot, then delete the
        other episode files (one cut short by an interrupt, or no longer held). A named file that is missing
        or damaged is a ValueError that names it, raised before any change."""
        episodes = []
        for name, T in state["files"]:
            path = os.path.join(self.directory, name)
            if not os.path.exists(path):
                raise ValueError(f"replay/{name} is missing")
            try:
                # opened here: np.load leaves a damaged zip's file open, and Python warns of it
                with open(path, "rb") as f, np.load(f, allow_pickle=False) as z:
                    # (reshaped: a run begun before the image had its channel axis stored (T + 1, 80, 80))
                    ep = {"obs": {k: z["obs_" + k].reshape((-1, *buf.obs[k].shape[1:])) for k in buf.obs},
                          **{k: z[k] for k in ("act", "rew", "term")}}
                if len(ep["act"]) != T or any(len(v) != T + 1 for v in ep["obs"].values()):
                    raise ValueError(f"{len(ep['act'])} transitions, not {T}")
            except Exception as e:
                raise ValueError(f"replay/{name} is damaged ({type(e).__name__}: {str(e)[:80]})")
            episodes.append(ep)
        buf.i = (state["i"] - sum(t for _, t in state["files"])) % buf.capacity    # where the oldest one began
        for ep in episodes:
            buf.add_episode(ep)
        if (buf.i, buf.n) != (state["i"], state["n"]):
            raise ValueError("the replay files do not fill the ring as the checkpoint says")
        self.files = collections.deque(list(f) for f in state["files"])
        names = {name for name, _ in state["files"]}
        for f in os.listdir(self.directory) if os.path.isdir(self.directory) else []:
            if f.startswith("ep_") and f.endswith(".npz") and f not in names:
                os.remove(os.path.join(self.directory, f))


# ---------------------------------------------------------------- the run
def update_seconds(sac, batch):
    """Seconds one SAC update takes, from three made on a copy with `batch` (zeros will do; sac, and torch's
    random numbers, are left as they were): for an ETA before the first update."""
    with torch.random.fork_rng(devices=[]):
        probe = copy.deepcopy(sac)
        probe.update(batch)                          # the first call allocates
        t0 = time.perf_counter()
        for _ in range(3):
            probe.update(batch)
    return (time.perf_counter() - t0) / 3


class Run:
    """A training run in its directory, new or continued where its checkpoint left it.

    cfg: the run's config (run_dir, train_episodes, warmup, updates, track, and the flags config.json keeps);
    state: {name: what ckpt.pt keeps}: objects with state_dict() / load_state_dict() (the SAC, the curriculum,
    the stop rule) and numpy Generators (their state); torch's RNG state is kept besides. buf: the replay
    buffer (its episodes go to replay/). After `Run(...)`: .episode, the first episode to run; .extended,
    whether a finished run is being trained on. Each episode: `lap('env')`, `lap('update')`, then `save(...)`.
    probe_update: seconds an update takes, for the ETA before the first; eval_episodes: the episodes this process
    plays in the evaluation after training, which the ETA counts at the last episodes' env time.
    """

    def __init__(self, cfg, state, buf, log, probe_update=None, eval_episodes=0):
        self.cfg, self.state, self.buf, self.log = cfg, state, buf, log
        self.dir = cfg.run_dir
        self.lock = lock(self.dir)                   # before anything is read or written: one writer a run dir
        try:
            self._open(probe_update, eval_episodes)
        except BaseException:
            os.close(self.lock)
            raise

    def _open(self, probe_update, eval_episodes):
        """The run dir read back where a checkpoint is (RunError where it cannot be), or begun."""
        cfg, buf, log = self.cfg, self.buf, self.log
        self.files = ReplayFiles(os.path.join(self.dir, "replay"), buf.capacity, buf.obs)
        ckpt, metrics = os.path.join(self.dir, "ckpt.pt"), os.path.join(self.dir, "metrics.csv")
        self.episode, self.total_steps, elapsed, replay = 0, 0, 0.0, {"i": 0, "n": 0, "files": []}
        if os.path.exists(ckpt):                     # else new, or stopped before its first episode was saved
            self.episode, self.total_steps, elapsed, replay = self._load(ckpt)
            if cfg.train_episodes < self.episode:
                raise RunError(f"the run has {self.episode} episodes; --train-episodes {cfg.train_episodes} is fewer")
        self.extended = os.path.exists(os.path.join(self.dir, "eval.json"))
        try:                                         # what the checkpoint holds; what it has not got goes
            rows = read_log(metrics, METRICS, self.episode)
            self.files.restore(buf, replay)          # (it checks its files before it deletes any)
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise RunError(f"cannot continue the run: {type(e).__name__}: {str(e).strip()[:120]}")
        write_log(metrics, METRICS, rows)
        if self.extended:                            # its policy's files and cached evaluations: *-epN.*
            set_aside(self.dir, self.episode)
        if not self.episode or self.extended:
            from dataclasses import asdict
            write_config(self.dir, {k: v for k, v in asdict(cfg).items() if k != "resume"})
        if self.episode:
            log(f"resumed {self.dir} at episode {self.episode} of {cfg.train_episodes}: networks, optimisers, "
                f"curriculum, random states, metrics.csv and the replay buffer ({len(buf)} transitions)"
                + (f"; the finished run's files are now *-ep{self.episode}.*" if self.extended else ""))
        self.tb = None
        if cfg.track:                                # CleanRL's convention: charts/, losses/; a resumed run hides
            from torch.utils.tensorboard import SummaryWriter    # what was written past its checkpoint
            self.tb = SummaryWriter(os.path.join(self.dir, "tb"), purge_step=self.episode + 1 if self.episode else None)
        self.probe_update, self.eval_episodes = probe_update, eval_episodes
        self.laps, self.update_s = {"env": [], "update": []}, []
        self.t0, self.t_lap = time.time() - elapsed, time.time()       # (a resumed run's first lap starts now)

    def _load(self, path):
        try:
            ck = load_file(path)
            for name, obj in self.state.items():
                if isinstance(obj, np.random.Generator):
                    obj.bit_generator.state = json.loads(ck[name])
                else:
                    obj.load_state_dict(ck[name])
            torch.set_rng_state(ck["torch_rng"])
            return int(ck["episode"]), int(ck["total_steps"]), float(ck["elapsed"]), json.loads(ck["replay"])
        except Exception as e:
            raise RunError(f"ckpt.pt is damaged or does not match this run's config ({type(e).__name__}: "
                           f"{str(e).strip()[:120]})")

    def lap(self, phase):
        """The seconds since the last lap count for `phase` ('env' or 'update') of this episode."""
        now = time.time()
        self.laps[phase].append(now - self.t_lap)
        self.t_lap = now

    def seconds(self):
        return time.time() - self.t0

    def save(self, episode, losses, threads, **columns):
        """End an episode: its row in metrics.csv (and TensorBoard), ckpt.pt, the replay file; then its progress
        line. episode: as tacrl.rollout gives it (its 'return' too); columns: the task's own columns of METRICS
        (sr15, e_r_mm, ex_r_mm, delta)."""
        self.episode += 1
        self.total_steps += len(episode["act"])
        self.files.add(episode, self.episode)
        mean = {k: round(float(np.mean([x[k] for x in losses])), 5) if losses else float("nan")
                for k in ("q_loss", "pi_loss", "alpha", "entropy")}
        env_s, update_s = self.laps["env"][-1], self.laps["update"][-1] if losses else 0.0
        self.update_s += [update_s] if losses else []
        row = {"episode": self.episode, "return": round(episode["return"], 3), "success": int(episode["term"][-1]),
               **{k: round(v, DIGITS.get(k, 3)) for k, v in columns.items()},
               "steps": len(episode["act"]), "total_steps": self.total_steps, "updates": len(losses), **mean,
               "env_s": round(env_s, 2), "update_s": round(update_s, 2), "elapsed_s": round(self.seconds(), 1)}
        with open(os.path.join(self.dir, "metrics.csv"), "a", newline="") as f:
            csv.DictWriter(f, METRICS).writerow(row)
        if self.tb is not None:
            self._track(row, episode)
        ck = {"episode": self.episode, "total_steps": self.total_steps, "elapsed": self.seconds(),
              "replay": json.dumps(self.files.state(self.buf)), "torch_rng": torch.get_rng_state()}
        for name, obj in self.state.items():
            ck[name] = json.dumps(obj.bit_generator.state) if isinstance(obj, np.random.Generator) else obj.state_dict()
        save_atomic(ck, os.path.join(self.dir, "ckpt.pt"))
        self.files.prune()                           # only now: the last checkpoint still needed those files
        self.log(f"ep {row['episode']:4d}/{self.cfg.train_episodes}  R {row['return']:7.1f}  succ {row['success']}  "
                 f"sr15 {row['sr15']:4.2f}  E_r {row['e_r_mm']:4.1f}mm  Ex_r {row['ex_r_mm']:4.1f}mm  delta "
                 f"{row['delta']:5.3f}  steps {row['steps']:3d}  env {env_s:4.1f}s  upd {update_s:4.1f}s "
                 f"({threads} thr)  elapsed {fmt_time(self.seconds())}  ETA {fmt_time(self.eta())}")

    def eta(self):
        """Seconds left: the episodes still to train (eta_seconds), then the evaluation's, each as long as the last
        EVAL_LIKE episodes' env time (the policy of the end plays it; the greedy one's episodes are no longer)."""
        train = eta_seconds(self.episode, self.cfg.train_episodes, self.cfg.warmup, self.laps["env"], self.update_s,
                            self.probe_update or 0.0)
        return train + self.eval_episodes * float(np.mean(self.laps["env"][-EVAL_LIKE:]))

    def _track(self, row, episode):
        for group, keys in TB_GROUPS.items():
            for k in keys:
                if np.isfinite(row[k]):                  # no losses during the warm-up
                    self.tb.add_scalar(f"{group}/{k}", row[k], row["episode"])
        if (row["episode"] - 1) % TB_IMAGE_EVERY == 0:   # what the policy saw as the episode began, (1, 80, 80)
            self.tb.add_image("obs/task_attention", episode["obs"]["image"][0], row["episode"], dataformats="CHW")
        self.tb.flush()

    def close(self):
        """TensorBoard's file, and the run dir's lock."""
        if self.tb is not None:
            self.tb.close()
        if self.lock is not None:
            os.close(self.lock)
            self.lock = None


def eta_seconds(done, episodes, warmup, env_s, update_s, probe_s):
    """Seconds the episodes after the first `done` of `episodes` will take: the mean env time `env_s` (s an
    episode so far), plus after the warm-up an update phase (the mean of `update_s`; before the first, probe_s)."""
    left = episodes - done
    with_updates = left - max(0, min(left, warmup - done))
    return left * float(np.mean(env_s)) + with_updates * (float(np.mean(update_s)) if update_s else probe_s)


def fmt_time(s):
    """Seconds as 1h02m or 3m07s."""
    s = int(s)
    return f"{s // 3600}h{s // 60 % 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"
