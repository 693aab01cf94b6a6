"""report.py's bookkeeping: which of the paper's comparisons a run joins, the command that reproduces
it, and the archived runs in results/ (written before issue 18) read through legacy.py."""
import dataclasses
import glob
import os

import pytest

import legacy
import report
import tacrl

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.parametrize("changes, expected", [
    ({}, {"methods": "ours", "roi": "task attention (Eq. 11)", "curriculum": "curriculum adaptive, 20 mm"}),
    ({"vanilla": True}, {"methods": "vanilla"}),
    ({"obs": "v"}, {"methods": "visual"}),
    ({"obs": "v", "critic": "multimodal"}, {"methods": "visual (critic multimodal)"}),   # the paper's critics
    ({"obs": "pt", "curriculum": "ex10"}, {"obs": "P-T"}),
    ({"curriculum": "ex10"}, {"obs": "Time-series P-T-V"}),
    ({"curriculum": "none", "error_mm": 10.0}, {"curriculum": "no curriculum, 10 mm"}),
    ({"curriculum": "g2-c10", "error_mm": 30.0}, {"curriculum": "curriculum g2-c10, 30 mm"}),
    ({"error_mm": 30.0}, {"curriculum": "curriculum adaptive, 30 mm"}),
    ({"roi": "full"}, {"roi": "ROI full"}),
    ({"curriculum": "g2-c10"}, {}),                       # at 20 mm: none of the paper's comparisons
    ({"lr": 1e-3}, {}),                                   # another learning setting: compared with nothing
])
def test_report_families(changes, expected):
    """Which of the paper's comparisons (Table 1, Fig. 9, 10, 11) a run's curves join in the report."""
    cfg = {**dataclasses.asdict(tacrl.Config()), **changes}
    assert report.families(cfg) == expected


def test_report_command_of_a_run():
    """The runs table gives each run the command that reproduces it: the flags off their defaults."""
    cfg = {**dataclasses.asdict(tacrl.Config()), "vanilla": True, "error_mm": 30.0, "seed": 2, "threads": 1,
           "run_dir": "runs/x"}
    assert report.command_of(cfg) == "python tacrl.py --task peg --seed 2 --error-mm 30 --vanilla"
    assert tacrl.parse_args(report.command_of(cfg).split()[2:]).vanilla


def test_archived_runs_read_through_the_legacy_shims():
    runs = sorted(os.path.dirname(f) for f in glob.glob(os.path.join(ROOT, "results", "**", "config.json"),
                                                          recursive=True))   # results/issue21/ holds runs too
    assert len(runs) >= 33
    for d in runs:
        cfg = tacrl.read_config(d)
        pi = tacrl.load_policy(os.path.join(d, "policy.pt"), cfg.task)
        assert pi.meta["roi"] == cfg.roi and pi.meta["obs"] == cfg.obs and "enc" not in pi.meta, d


def test_a_run_that_used_a_removed_option_is_refused():
    with pytest.raises(ValueError, match="aux-weight"):
        legacy.upgrade_config({"task": "peg", "aux_weight": 1.0})
