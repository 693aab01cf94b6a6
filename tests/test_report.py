"""report.py's bookkeeping: which of the paper's comparisons a run joins, the command that reproduces
it, and runs written before issue 18 (those archived in results/) read through legacy.py."""
import dataclasses
import json

import numpy as np
import pytest
import torch

import legacy
import report
import tacrl

@pytest.mark.parametrize("changes, expected", [
    ({}, {"methods": "ours", "roi": "task attention (Eq. 11)", "curriculum": "curriculum adaptive, 20 mm"}),
    ({"vanilla": True}, {"methods": "vanilla"}),
    ({"obs": "v"}, {"methods": "visual"}),
    ({"obs": "ts-ptk"}, {"methods": "keypoint"}),
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


def test_runs_of_the_older_formats_read_through_the_legacy_shims(tmp_path):
    # as the runs archived in results/ before issue 18 were written: options since removed (at their 'off'
    # values) or moved to seeds.py and report.py in config.json; the policy's encoder under 'actor_enc'
    (tmp_path / "config.json").write_text(json.dumps({**dataclasses.asdict(tacrl.Config()), "aux_weight": 0.0,
                                                      "prior_weight": 0.0, "seeds": "0,1", "archive": ""}))
    sac = tacrl.make_sac(tacrl.Config(), "cpu")
    old = {"format": "tacrl-policy-1", "task": "peg", "obs": "ts-ptv", "roi": "task", "vanilla": False, "ex_r": 0.02,
           "e_r_max": 0.02, "enc": sac.enc.state_dict(), "actor_enc": sac.actor_enc.state_dict(),
           "actor": sac.actor.state_dict()}
    torch.save(old, tmp_path / "policy.pt")
    assert legacy.read_config(str(tmp_path)) == tacrl.Config()
    pi = legacy.load_policy(str(tmp_path / "policy.pt"), "peg")
    assert pi.meta["roi"] == "task" and "enc" not in pi.meta
    obs = {"image": np.zeros((80, 80), np.uint8), "pose_hist": np.zeros((32, 6), np.float32),
           "wrench_hist": np.zeros((32, 6), np.float32)}
    assert np.allclose(pi(obs), sac.act(obs, deterministic=True))     # the actor's own encoder, not the critics'


def test_a_run_that_used_a_removed_option_is_refused():
    with pytest.raises(ValueError, match="aux-weight"):
        legacy.upgrade_config({"task": "peg", "aux_weight": 1.0})
