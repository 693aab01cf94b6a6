"""command.py: tacrl.py's command line (cli.py holds what every command shares): its flags parsed and checked
against each other and the files they name, before any work; a run directory's default name and config; --eval's
run; and how torch uses the CPU. It takes the Config class from its caller and imports nothing of tacrl.py.
"""
import ctypes
import importlib
import json
import os
import sys
import tempfile
from dataclasses import fields, replace

import torch

import tacrl_flat  # noqa: F401  (first: where another package shadows one of our modules, one line says so)
import baselines
import contexts
import evaluate
import rundir
import scene
import sim
from cli import (ArgError, check_bounds, check_dir_writable, check_new_file, describe, format_config, from_dict,
                 parse)

RESUME_MAY_SET = ("resume", "train_episodes", "stop_held", "threads", "track")   # to extend a run; nothing else changes
NOT_LEARNING = ("eval", "resume", "run_dir", "track", "threads", "device", "gui", "episodes", "json", "video",
                "eval_levels", "train_episodes", "stop_held")     # how a run is run, evaluated or extended
# The critics study's flags (issues 31 and 50; docs/critics.md) and their defaults, retired to commit
# STUDY_COMMIT. A run dir written before reads on where they have the values under which it computes what today's
# code does: these, and for --critic multimodal, STUDY_MULTIMODAL (the setting that learned best, today's).
STUDY_COMMIT = "612813e"
STUDY_DEFAULTS = {"shift": 0, "drq": 1, "critic_extra": False, "next_encoder": "target", "nstep": 1, "aux_reward": 0.0,
                  "aux_offset": 0.0, "actor_encoder": "shared", "fusion_norm": "joint", "image_encoder": "cnn",
                  "q_norm": False, "q_dropout": 0.0, "q_heads": 2, "reset": 0, "aux_wrench": 0.0, "aux_recon": 0.0,
                  "aux_curl": 0.0, "enc_lr": 0.0, "image_feat": 6}
STUDY_MULTIMODAL = {"critic_extra": True, "next_encoder": "online", "fusion_norm": "modality", "q_norm": True}
RUN_NAME_TAGS = (("clearance_mm", "c"), ("tilt_deg", "tilt"), ("updates", "u"), ("warmup", "w"), ("batch", "b"),
                 ("buffer", "buf"), ("lr", "lr"), ("gamma", "g"), ("target_entropy", "ent"))   # default_run_dir's tail


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


def use_cpu(device="cpu"):
    """Torch on the CPU as tacrl runs it: every op on the thread that calls it (an update's second core is
    policy.Helper's thread, acting needs one), and malloc keeping what it frees (keep_freed_memory). With
    torch's default of a thread a core, OpenMP's threads wait for each other at every op: beside one busy program
    that slowed updates 3-4x on 2 cores (bench/bench_threads.py)."""
    if device == "cpu":
        torch.set_num_threads(1)
        keep_freed_memory()


def cores(cfg):
    """The cores a run uses (--threads; 0: 2 where there are 2): an update's two halves side by side
    (policy.Helper), and an evaluation's episodes in two processes (evaluate.Worker)."""
    return cfg.threads or min(2, os.cpu_count() or 1)


def warn_oversubscribed(prog, threads, processes=1, cores=None):
    """A warning line on stderr where `processes` runs of `threads` threads an update each ask for more threads
    than there are cores: they can only take turns, each run slower than alone on a core."""
    cores = cores or os.cpu_count() or 1
    if threads * processes > cores:
        print(f"{prog}: warning: {processes} x {threads} threads an update on {cores} cores: they will take turns "
              f"(use --threads {max(1, cores // processes)})", file=sys.stderr)


def parse_args(config_cls, argv, description):
    """argv -> a checked Config. A flag that would not apply (a training flag with --eval, or the other way
    round; with --resume, all but those of RESUME_MAY_SET) is a mistake, not silently ignored."""
    given = parse(config_cls, argv, description)                    # only the flags on the command line
    mode = "eval" if "eval" in given else "train"
    for f in fields(config_cls):
        if f.name in given and f.metadata["mode"] not in (None, mode):
            raise ArgError(f"--{f.name.replace('_', '-')} is for {'--eval' if mode == 'train' else 'training'}: it "
                           f"would have no effect {'when training' if mode == 'train' else 'with --eval'}")
    if "resume" in given:
        others = [f"--{k.replace('_', '-')}" for k in given if k not in RESUME_MAY_SET]
        if others:
            raise ArgError(f"--resume continues a run as its config.json says: {', '.join(others)} cannot change "
                           f"it (--train-episodes N extends it)")
        run_dir = given.pop("resume")
        cfg = replace(load_config(config_cls, run_dir), **given)
        saved = episodes_saved(run_dir)          # ckpt.pt lags metrics.csv by the episode in flight at most: refused
        if cfg.train_episodes < saved - 1:       # here before any env is built (rundir.Run checks the checkpoint)
            raise ArgError(f"--resume {run_dir!r}: the run has {saved} episodes; --train-episodes "
                           f"{cfg.train_episodes} is fewer")
        if os.path.exists(os.path.join(run_dir, "eval.json")) and not set(given) - {"threads", "track"}:
            raise ArgError(f"--resume {run_dir!r}: the run is finished; extend it with --train-episodes N (and "
                           f"--stop-held 0 to train past the point where it stopped as learned)")
    else:
        cfg = config_cls(**with_presets(config_cls, given))
    check(cfg)
    return cfg


def with_presets(config_cls, given):
    """The flags given, with those of each preset flag given (Config.PRESETS: --robust) that the command line does
    not set itself."""
    for flag, preset in getattr(config_cls, "PRESETS", {}).items():
        if given.get(flag):
            given = {**preset, **given}
    return given


def preset_defaults(config_cls, flags):
    """The config a run's flags (a dict) are told against: the defaults, under the presets the run set (--robust)."""
    return replace(config_cls(), **with_presets(config_cls, {k: v for k, v in flags.items()
                                                             if k in getattr(config_cls, "PRESETS", {})}))


def check(cfg):
    """Every value, and every file the command will write, before any work starts."""
    check_bounds(cfg)
    try:
        levels = [float(x) for x in cfg.eval_levels.split(",")]
    except ValueError:
        levels = []
    e_r_max = max(cfg.error_mm, sim.E_R_FINAL * 1000)      # the training env's largest range (ROI, X_i), mm
    randomize = sim.randomize_problem(cfg.families, cfg.context)      # as the env checks it, before any work
    for bad, msg in [
            (cfg.eval and cfg.eval not in baselines.NAMES and not os.path.isfile(cfg.eval),
             f"--eval must be {', '.join(baselines.NAMES)}, an existing policy.pt or a run's ckpt.pt, not "
             f"{cfg.eval!r}"),
            (cfg.eval == "two-step" and cfg.task != "peg", "--eval two-step is the peg-in-hole baseline (Table 1)"),
            (not cfg.eval and contexts.drawn_family(cfg.context),
             f"--context {cfg.context} draws a scene each episode: it is for --eval (training draws its own with "
             "--randomize)"),
            (randomize, f"--randomize takes {randomize}, comma-separated, not "
             f"{cfg.randomize!r}" + (f" with --context {cfg.context}" if cfg.context != "train" else "")),
            (cfg.obs == "ts-ptk" and cfg.task != "peg", "--obs ts-ptk (keypoint RL) finds the peg board's hole; the "
                                                        "gear's shaft is no keypoint it finds (Table 1 is the peg's)"),
            (cfg.buffer < max(cfg.batch, sim.MAX_STEPS), f"--buffer {cfg.buffer} must hold an episode ({sim.MAX_STEPS} "
                                                         f"transitions) and a batch (--batch {cfg.batch})"),
            (cfg.video and os.path.splitext(cfg.video)[1].lower() not in evaluate.VIDEO_CODECS,
             f"--video must name a .webm (VP9) or .mp4 (H.264) file, not {cfg.video!r}"),
            (not levels or not all(0.0 <= x <= e_r_max for x in levels),
             f"--eval-levels must be comma-separated error ranges in 0..{e_r_max:g} mm (the run's env covers "
             f"--error-mm, and at least 20), not {cfg.eval_levels!r}"),
            (cfg.device == "cuda" and not torch.cuda.is_available(), "--device cuda: no CUDA device is available"),
            (cfg.gui and scene.display_problem(), f"--gui: {scene.display_problem()}")]:
        if bad:
            raise ArgError(msg)
    if cfg.track:
        try:
            importlib.import_module("torch.utils.tensorboard")
        except ImportError:
            raise ArgError("--track logs to TensorBoard, which is not installed: pip install -e '.[track]'")
    warn_oversubscribed("tacrl", cfg.threads)
    for name in [x for x in ("json", "video") if getattr(cfg, x)]:   # written after the work: checked before it
        check_new_file(getattr(cfg, name), f"--{name}")
    if cfg.video:                                   # the codec, tried on a scratch file: a format this OpenCV
        with tempfile.TemporaryDirectory() as tmp:  # cannot write is a mistake before any work, not after it
            try:
                probe = evaluate.open_video(os.path.join(tmp, "probe" + os.path.splitext(cfg.video)[1]), (64, 48))
            except ValueError as e:
                raise ArgError(f"--video {cfg.video!r}: {e}")
            with scene.quiet_c_output():
                probe.release()
    if cfg.device == "auto":                        # cuda where there is one
        cfg.device = "cuda" if torch.cuda.is_available() else "cpu"
    if not cfg.eval:
        cfg.run_dir = cfg.run_dir or default_run_dir(cfg)
        check_dir_writable(cfg.run_dir, "--run-dir")
        left = os.listdir(cfg.run_dir) if os.path.isdir(cfg.run_dir) else []
        busy = rundir.busy(cfg.run_dir)           # a second writer: the first's files stay as they are
        if busy:
            raise ArgError(f"--{'resume' if cfg.resume else 'run-dir'} {cfg.run_dir!r}: {busy}")
        if not cfg.resume and "config.json" in left:
            raise ArgError(f"{cfg.run_dir!r} already holds a run: continue it with --resume {cfg.run_dir} "
                           f"or pick another --run-dir")
        if not cfg.resume and set(left) - {rundir.LOG}:
            raise ArgError(f"--run-dir {cfg.run_dir!r} is not empty: a new run starts in a new or empty directory")


def default_run_dir(cfg):
    """runs/<task>-[robust-][vanilla-]<obs>-<curriculum>[-e<E_r mm>][-roi-<roi>][-ctx-<context>][-<critic>][-aug<s>]
    [-rand-<families>][-imgnorm-<norm>][-<tag><value> of RUN_NAME_TAGS]-s<seed>: the flags of the baselines,
    ablations and options are in its name (beside --robust, those that differ from its), so that no run overwrites
    another's directory."""
    default = preset_defaults(type(cfg), vars(cfg))     # the config's defaults (and --robust's)
    robust = getattr(cfg, "robust", False)
    name = f"{cfg.task}-{'robust-' if robust else ''}{'vanilla-' if cfg.vanilla else ''}{cfg.obs}-{cfg.curriculum}"
    name += f"-e{cfg.error_mm:g}" if cfg.error_mm != default.error_mm else ""
    name += f"-roi-{cfg.roi}" if cfg.roi != "task" else ""
    name += f"-ctx-{cfg.context}" if cfg.context != default.context else ""
    name += f"-{cfg.critic}" if cfg.critic != default.critic else ""
    name += f"-aug{cfg.augment:g}" if cfg.augment else ""
    name += f"-rand-{cfg.randomize.replace(',', '+') or 'none'}" if cfg.randomize != default.randomize else ""
    name += f"-imgnorm-{cfg.image_norm}" if cfg.image_norm != default.image_norm else ""
    for field, tag in RUN_NAME_TAGS:                    # the scene and SAC's numbers, where not the defaults
        value = getattr(cfg, field)
        name += f"-{tag}{value:g}" if value != getattr(default, field) else ""
    return os.path.join("runs", f"{name}-s{cfg.seed}")


def study_options(d):
    """Pops the critics study's flags from a config dict; returns those whose values today's code does not compute
    (such a run is the study's: its code is commit STUDY_COMMIT)."""
    study = {k: d.pop(k) for k in list(d) if k in STUDY_DEFAULTS}
    now = {**STUDY_DEFAULTS, **(STUDY_MULTIMODAL if d.get("critic") == "multimodal" else {})}
    return {k: v for k, v in {**STUDY_DEFAULTS, **study}.items() if v != now[k]} if study else {}


def read_config(config_cls, run_dir):
    """A run's config.json as a Config; OSError, or ValueError if a value is not of its flag's type and choices, or
    if the run used options of the critics study."""
    d = rundir.read_config(run_dir)
    study = study_options(d)
    if study:
        raise ValueError(f"a run of the critics study ({', '.join(study)}): its code is commit {STUDY_COMMIT}")
    return from_dict(config_cls, d)


def episodes_saved(run_dir):
    """The rows of a run's metrics.csv; 0 where it has none, or none that can be read (rundir.Run says why)."""
    try:
        return len(rundir.read_metrics(run_dir)["episode"])
    except (OSError, ValueError, KeyError):
        return 0


def load_config(config_cls, run_dir):
    try:
        cfg = read_config(config_cls, run_dir)
    except NotADirectoryError:
        raise ArgError(f"--resume {run_dir!r} is a file, not a run directory")
    except FileNotFoundError:
        raise ArgError(f"--resume {run_dir!r}: no config.json there (not a run directory)")
    except (OSError, ValueError) as e:              # a directory named config.json, bad JSON, a wrong type
        raise ArgError(f"--resume {run_dir!r}: config.json is unreadable ({describe(e)})")
    cfg.run_dir, cfg.resume, cfg.eval = run_dir, run_dir, ""
    return cfg


def load_policy(load, path, task, device="cpu"):
    """--eval's policy.pt (load(path, device): the caller's reader of policy files), or a one-line mistake: a file
    that is not one, or one for another task."""
    try:
        pi = load(path, device)
    except ValueError as e:
        raise ArgError(f"--eval {path!r}: {e}")
    if pi.meta["task"] != task:
        raise ArgError(f"--eval {path!r}: this policy was trained for --task {pi.meta['task']}, not {task}")
    return pi


def run_evaluation(cfg, load=evaluate.load_policy):
    """--eval: a policy file (load(path, device) reads it: tacrl.load_policy takes a ckpt.pt too), the hand-designed
    policy alone or the two-step baseline, at --error-mm."""
    pi = None if cfg.eval in baselines.NAMES else load_policy(load, cfg.eval, cfg.task, cfg.device)
    if pi is not None and pi.meta["roi"] != cfg.roi:      # its encoder learned that view, not another
        raise ArgError(f"--eval {cfg.eval!r}: this policy was trained with --roi {pi.meta['roi']}, not {cfg.roi}")
    if pi is not None and cfg.error_mm > pi.meta["e_r_max"] * 1000 + 1e-6:   # Eq. 11's ROI would widen
        raise ArgError(f"--error-mm {cfg.error_mm:g}: this policy's view covers {pi.meta['e_r_max'] * 1000:g} mm")
    print(format_config(cfg), flush=True)
    use_cpu(cfg.device)
    with evaluate.eval_env(cfg.task, pi, cfg.context, cfg.roi, cfg.clearance_mm, cfg.error_mm, cfg.gui) as env:
        video = evaluate.open_video(cfg.video, env.world.render_external().shape[1::-1]) if cfg.video else None
        act = pi if pi is not None else baselines.make(cfg.eval, env)
        if cfg.eval == "two-step":
            print(f"two-step: calibrated the image -> offset map, median error {act.fit_error * 1000:.2f} mm")
        shared = pi is not None and cfg.episodes > 1 and not cfg.gui        # (a worker plays a policy.pt's alone)
        try:                                          # the seeds of eval.json
            with evaluate.second_core(cores(cfg) if shared else 1, cfg.device) as worker:
                row = evaluate.evaluate(env, act, cfg.episodes, evaluate.EVAL_SEED + cfg.seed, video, worker=worker)
        finally:
            if video is not None:
                with scene.quiet_c_output():
                    video.release()
        row.update({"task": cfg.task, "policy": cfg.eval, "error_mm": cfg.error_mm,
                    "ex_r_mm": round(env.ex_r * 1000, 3), "context": cfg.context, "roi": cfg.roi, "seed": cfg.seed})
    print(evaluate.format_row(f"{cfg.eval if pi is None else 'TA-MRP'} {cfg.task} {cfg.error_mm:g}mm", row))
    if cfg.json:
        with open(cfg.json, "w") as f:
            json.dump(row, f, indent=2)
        print(f"wrote {cfg.json}")
