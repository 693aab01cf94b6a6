"""legacy.py: reads the files of runs made before issue 18, which removed the options that never helped
(--aux-weight, --prior-weight) and moved --seeds, --archive and --report to seeds.py and report.py.
The runs archived in results/ are such runs. Delete this file, and its two calls in tacrl.py, once
every run in results/ has been re-made.
"""
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
        d["format"] = "tacrl-policy-2"
    return d
