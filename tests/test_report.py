"""report.py's bookkeeping: which of the paper's comparisons a run joins, the command that reproduces
it."""
import dataclasses
import re

import numpy as np
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


@pytest.mark.parametrize("critic, study, today", [
    ("privileged", {"shift": 0, "q_norm": False, "next_encoder": "target"}, True),      # written before: the same
    ("privileged", {"q_norm": True}, False),
    ("multimodal", {"critic_extra": True, "next_encoder": "online", "fusion_norm": "modality", "q_norm": True}, True),
    ("multimodal", {"critic_extra": True, "next_encoder": "online", "fusion_norm": "modality"}, False),   # no q_norm
    ("multimodal", {}, True),                                                            # written today
])
def test_a_run_of_the_critics_study_reads_in_the_report_and_nowhere_else(tmp_path, critic, study, today):
    """The study's flags left the core for a git tag: a run dir that used them is refused by what would train or
    rebuild it, and the report describes it by the flags in which it differs from today's code."""
    import json
    cfg = {**dataclasses.asdict(tacrl.Config()), "critic": critic, **study}
    (tmp_path / "config.json").write_text(json.dumps(cfg))
    if today:
        assert tacrl.read_config(str(tmp_path)).critic == critic
        assert report.method_of(report.read_config(str(tmp_path))) == ("ours" if critic == "privileged" else
                                                                        "ours (critic multimodal)")
    else:
        with pytest.raises(ValueError, match="critics-study"):
            tacrl.read_config(str(tmp_path))
        assert "q_norm" in report.method_of(report.read_config(str(tmp_path)))


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


def test_an_ablation_in_numbers_has_a_row_a_setting_over_its_seeds():
    """Figs. 9-11 in numbers: each setting's cells are over its seeds, seed by seed in brackets; a run that never
    reached its final range says so; one setting alone is no comparison."""
    def run(obs, seed, e_r_most, trained, sr):
        cfg = {**dataclasses.asdict(tacrl.Config()), "task": "gear", "obs": obs, "curriculum": "ex10", "seed": seed,
               "stop_held": 0, "train_episodes": 200}
        e_r = np.minimum(np.arange(200) * 0.25, e_r_most)           # mm, reaches 20 at episode 81 where it may
        m = {"episode": np.arange(1, 201), "e_r_mm": e_r, "success": np.r_[np.zeros(150), np.ones(50) * trained]}
        rows = [{"error_mm": x, "success_rate": sr * x / 20, "completion_time_s": [4.0, 1.0]} for x in report.LEVELS]
        return {"cfg": cfg, "m": m, "eval": {"rows": rows}, "dir": f"runs/{obs}-s{seed}"}
    runs = [run("pt", 0, 5.0, 0.0, 0.0), run("pt", 1, 7.0, 1.0, 0.2),
            run("ts-ptv", 0, 20.0, 1.0, 1.0), run("ts-ptv", 1, 20.0, 1.0, 0.9), run("ts-ptv", 2, 20.0, 1.0, 0.7)]
    table = report.ablation_table(runs, "gear", "obs")
    assert len(table) == 2 + 2 and report.ablation_table(runs[:2], "gear", "obs") == []
    pt, ptv = table[2].split(" | "), table[3].split(" | ")
    assert pt[0] == "| P-T" and pt[1:4] == ["2", "never / never", "6.0 / 6.0"]
    assert pt[4] == "0.50 [0.00, 1.00] (0.00 / 1.00)" and pt[5] == "0.10 [0.00, 0.20] (0.00 / 0.20)"   # all resamples
    assert ptv[0] == "| Time-series P-T-V" and ptv[1:4] == ["3", "81 / 81 / 81", "20.0 / 20.0"]
    mean, lo, hi = (float(x) for x in re.match(r"([\d.]+) \[([\d.]+), ([\d.]+)\] \(1.00 / 0.90 / 0.70\)$",
                                               ptv[5]).groups())
    assert mean == 0.87 and 0.70 <= lo < mean < hi <= 1.00 and ptv[6] == "4.00"     # within the seeds
    assert ptv[7] == "0.22 / 0.43 / 0.65 / 0.87 |"
    assert report.ablation_table(runs, "peg", "obs") == [] and report.ablation_table(runs, "gear", "roi") == []
    one = report.ablation_table(runs[1:4], "gear", "obs")[2].split(" | ")     # a setting of one seed: no spread
    assert one[0] == "| P-T" and one[1] == "1" and one[4:6] == ["1.00", "0.20"]


def test_a_planned_run_is_counted_for_its_own_experiment_alone():
    """The ROI ablation's task-attention run and the curriculum ablation's adaptive run share a name at two
    budgets (200 and 300 episodes): a finished run counts for the experiment whose budget it trained."""
    import sweep
    run = {"dir": "results/gear-roi/gear-ts-ptv-adaptive-s0", "m": {"episode": list(range(1, 201))},
           "cfg": {**dataclasses.asdict(tacrl.Config()), "task": "gear", "train_episodes": 200, "stop_held": 0}}
    plan = lambda exp: [sweep.config_of([*row, "--seed", "0"]) for row in sweep.EXPERIMENTS[exp]]    # noqa: E731
    assert sum(report.is_planned(run, p) for p in plan("gear-roi")) == 1
    assert sum(report.is_planned(run, p) for p in plan("gear-curriculum")) == 0
    unfinished = {**run, "m": {"episode": list(range(1, 150))}}
    assert sum(report.is_planned(unfinished, p) for p in plan("gear-roi")) == 0


def test_the_objects_study_shows_the_policy_the_scene_without_its_objects_and_changes_nothing_else():
    import objects
    import scene
    import sim
    block = scene.Context(objects=(((0.01, 0.01, 0.012), (0.045, 0.0), (0.8, 0.1, 0.1, 1)),), on_board=True)
    images = {}
    for name, ctx, twin in (("plain", block, False), ("twin", block, True), ("none", scene.Context(), False)):
        with sim.AssemblyEnv("peg", ctx, e_r=0.02) as env:
            last = {}
            if twin:
                objects.twin_renders(env, blind=False, last=last)
            obs, _ = env.reset(seed=4)
            obs2, *_ = env.step(np.zeros(6))
            images[name] = obs2["image"]
            images["blind"] = last.get("blind", images.get("blind"))
    np.testing.assert_array_equal(images["twin"], images["plain"])      # what the policy sees, bit for bit
    np.testing.assert_array_equal(images["blind"], images["none"][0])      # the same scene, the same noise, no objects
    assert (images["plain"] != images["none"]).mean() > 0.01            # and the block is in view


def test_a_readme_table_is_made_anew_under_its_caption_or_refused(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("# x\n\nTable 1 in today's world: ...\n\n| a |\n|---|\n| 1 |\n\nrest\n")
    report.write_readme_table(str(readme), report.README_TABLE1, ["| b |", "|---|", "| 2 |"], log=lambda *_: None)
    assert readme.read_text() == "# x\n\nTable 1 in today's world: ...\n\n| b |\n|---|\n| 2 |\n\nrest\n"
    with pytest.raises(report.ArgError):                  # no such caption: one line, nothing written
        report.write_readme_table(str(readme), "Table 9", ["| c |"], log=lambda *_: None)


def test_the_readme_contexts_table_gives_each_background_its_mean_and_worst_seed(tmp_path):
    import contexts
    row = lambda sr: [{"success_rate": s, "cumulative_reward": [10.0 * s]} for s in sr]      # noqa: E731  (5..20 mm)
    table = {("peg", "task attention", c): [row([1, 1, 1, 1]), row([1, 1, 0.9, 0.8])] for c in contexts.CONTEXTS}
    table[("peg", "task attention", "bg-light")] = [row([1, 1, 0.5, 0.4]), row([1, 1, 0.3, 0.2])]
    readme = tmp_path / "README.md"
    readme.write_text(f"{report.README_CONTEXTS}:\n\n| old |\n")
    report.write_readme_contexts(table, report.LEVELS, str(readme), log=lambda *_: None)
    cells = readme.read_text().splitlines()[4].split(" | ")
    assert cells[0] == "| peg, task attention" and cells[1] == "2" and cells[2] == "0.90 (0.80)"
    assert cells[3] == "0.95-0.95 / 0.90-0.90" and cells[6] == "0.30 (0.20)"      # training, the places, bg-light


def test_the_readme_families_table_shows_the_default_and_the_robust_option_alone(tmp_path):
    import sim
    option = report.OPTION_VIEW
    old = report.view_of({**dataclasses.asdict(tacrl.Config()), "randomize": "light", "image_norm": "image"})
    by = lambda sr: {"train": sr, **{f: sr for f in sim.FAMILIES}}                     # noqa: E731
    families = {("peg", "task attention"): by([1.0, 0.9]), ("peg", option): by([0.95]), ("peg", old): by([0.5])}
    readme = tmp_path / "README.md"
    readme.write_text(f"{report.README_FAMILIES}:\n\n| old |\n")
    report.write_readme_families(families, str(readme), log=lambda *_: None)
    rows = readme.read_text().splitlines()[4:]
    assert [r.split(" | ")[:3] for r in rows] == [["| peg, task attention", "2", "0.95 (0.90)"],
                                                   [f"| peg, {option}", "1", "0.95 (0.95)"]]
    assert "tilt_deg 1.0" in option and "mixed" in option


def test_the_orders_sentence_says_it_holds_only_where_each_interval_lies_above_the_next():
    paper = lambda **srs: {k + report.PAPER_CRITICS: np.array(v) for k, v in srs.items()}   # noqa: E731
    apart = paper(ours=[0.9, 0.95, 1.0], keypoint=[0.6, 0.65, 0.7], visual=[0.0, 0.05, 0.1], vanilla=[0.0, 0.0, 0.1])
    assert report.ordering_sentence(apart).endswith("under its own critics: it holds.")
    overlap = dict(apart, **paper(keypoint=[0.6, 0.65, 0.95]))
    said = report.ordering_sentence(overlap)
    assert "not shown" in said and "ours is above keypoint RL on the mean only" in said
    assert report.ORDERING.fullmatch(said)                    # the README's pattern takes the whole of it
    below = {k: v for k, v in paper(ours=[0.3, 0.4], keypoint=[0.5, 0.6]).items()}
    said = report.ordering_sentence(below)
    assert "ours is not above keypoint RL" in said and "visual RL and vanilla RL are not run yet" in said


def test_the_leave_one_out_has_a_table_of_its_own_named_by_the_part_left_out():
    import sim
    by = lambda sr: {"train": sr, **{f: sr for f in sim.FAMILIES}}                     # noqa: E731
    view = {out: v for v, out in report.LOO_VIEWS.items()}
    no_tilt, no_light = view["--tilt-deg"], view["light"]
    families = {("peg", "task attention"): by([1.0]), ("peg", report.OPTION_VIEW): by([0.95, 1.0]),
                ("peg", no_tilt): by([0.5]), ("peg", no_light): by([0.25])}
    md = report.family_table(families, episodes=20)
    split = next(i for i, line in enumerate(md) if line.startswith("What each part"))
    main = [r.split(" | ")[1] for r in md[:split] if r.startswith("| peg")]
    assert main == ["task attention", report.OPTION_VIEW]
    loo = [r.split(" | ")[1:4] for r in md[split:] if r.startswith("| peg")]
    assert loo == [["nothing (the option)", "2", "0.97 (0.95-1.00)"], ["`light`", "1", "0.25"],
                   ["`--tilt-deg`", "1", "0.50"]]                                   # the option first, then as planned
    alone = report.family_table({("peg", no_light): by([0.25])}, episodes=20)          # a run of it, reported alone
    assert [r.split(" | ")[1] for r in alone if r.startswith("| peg")] == ["`light`"]
