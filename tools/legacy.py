"""legacy.py: reads the runs archived in results/ before issue 18 and in policy format 1, for report.py
and the benches: issue 18 removed options that never helped (--aux-weight, --prior-weight) and moved
--seeds, --archive and --report to seeds.py and report.py; policy format 2 renamed the actor's encoder.
The training and evaluation code (tacrl.py, evaluate.py) reads only today's files. Delete this file once
every run in results/ has been re-made.
"""
import evaluate
import policy
import rundir
import tacrl

REMOVED_OPTIONS = {"aux_weight": 0.0, "prior_weight": 0.0}       # at their 'off' values
MOVED_OPTIONS = ("seeds", "archive", "report", "report_dir")


def upgrade_config(d):
    """An old config.json's dict -> today's keys. A run that used a removed option is refused: it
    cannot be read as one that did not. What is not a dict is left for the config's own check."""
    if not isinstance(d, dict):
        return d
    for k, off in REMOVED_OPTIONS.items():
        if d.pop(k, off) != off:
            raise ValueError(f"the run used --{k.replace('_', '-')}, an option that no longer exists")
    for k in MOVED_OPTIONS:
        d.pop(k, None)
    return d


def upgrade_policy(d):
    """An old policy.pt's dict -> today's: the actor's encoder was 'actor_enc' (privileged critics) or
    the encoder it shared with the critics, 'enc'; today it is 'encoder'."""
    if isinstance(d, dict) and d.get("format") == "tacrl-policy-1":
        enc = d.pop("enc")
        d["encoder"] = d.pop("actor_enc", enc)
        d["format"] = policy.POLICY_FORMAT
    return d


def read_config(run_dir):
    """A run's config.json, of any version, as a tacrl.Config (ValueError where it cannot be)."""
    return tacrl.from_dict(tacrl.Config, upgrade_config(rundir.read_config(run_dir)))


def load_policy(path, task=None, device="cpu"):
    """A policy.pt of any format as a policy.TrainedPolicy (ValueError where it is not one, or is for another task)."""
    pi = policy.TrainedPolicy(upgrade_policy(policy.load_file(path, device)), device)
    missing = set(evaluate.POLICY_META) - set(pi.meta)
    if missing or (task is not None and pi.meta["task"] != task):
        raise ValueError(f"{path}: not a {task or ''} policy with its meta")
    return pi
