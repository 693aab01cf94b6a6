"""report.py's bookkeeping: which of the paper's comparisons a run joins, the command that reproduces
it."""
import dataclasses

import pytest

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


@pytest.mark.parametrize("changes, episodes, expected", [
    ({}, 200, set()),                                                  # stopped when learned: a budget of its own
    ({"stop_held": 0, "train_episodes": 200}, 200, {"methods", "roi"}),   # Table 1 and Fig. 11: 200 episodes
    ({"stop_held": 0, "train_episodes": 200}, 150, set()),                  # not finished
    ({"stop_held": 0, "train_episodes": 192}, 192, set()),                  # another budget
    ({"stop_held": 0, "train_episodes": 300}, 300, {"curriculum"}),        # Fig. 10: 300 episodes
    ({"stop_held": 0, "train_episodes": 300, "curriculum": "none", "error_mm": 30.0}, 300, {"curriculum"}),
])
def test_a_comparison_takes_the_runs_of_its_budget_alone(changes, episodes, expected):
    """Every row of one of the paper's comparisons trained the same number of episodes, as the paper's rows."""
    run = {"cfg": {**dataclasses.asdict(tacrl.Config()), **changes}, "m": {"episode": list(range(1, episodes + 1))}}
    assert set(report.fam_of(run)) == expected
