"""The report's bookkeeping (tools/runs.py, results.py, scenes.py): which of the paper's comparisons a run joins, the
command that reproduces it, the tables it makes of them and what it calls each setting."""
import dataclasses
import re

import numpy as np
import pytest

import results
import runs
import scenes
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
    assert runs.families(cfg) == expected


def test_report_command_of_a_run():
    """The runs table gives each run the command that reproduces it: the flags off their defaults."""
    cfg = {**dataclasses.asdict(tacrl.Config()), "vanilla": True, "error_mm": 30.0, "seed": 2, "threads": 1,
           "run_dir": "runs/x"}
    assert runs.command_of(cfg) == "python tacrl.py --task peg --seed 2 --error-mm 30 --vanilla"
    assert tacrl.parse_args(runs.command_of(cfg).split()[2:]).vanilla


@pytest.mark.parametrize("critic, study, today", [
    ("privileged", {"shift": 0, "q_norm": False, "next_encoder": "target"}, True),      # written before: the same
    ("privileged", {"q_norm": True}, False),
    ("multimodal", {"critic_extra": True, "next_encoder": "online", "fusion_norm": "modality", "q_norm": True}, True),
    ("multimodal", {"critic_extra": True, "next_encoder": "online", "fusion_norm": "modality"}, False),   # no q_norm
    ("multimodal", {}, True),                                                            # written today
])
def test_a_run_of_the_critics_study_reads_in_the_report_and_nowhere_else(tmp_path, critic, study, today):
    """The study's flags left the core for a commit: a run dir that used them is refused by what would train or
    rebuild it, and the report describes it by the flags in which it differs from today's code."""
    import json
    cfg = {**dataclasses.asdict(tacrl.Config()), "critic": critic, **study}
    (tmp_path / "config.json").write_text(json.dumps(cfg))
    if today:
        assert tacrl.read_config(str(tmp_path)).critic == critic
        assert runs.method_of(runs.read_config(str(tmp_path))) == ("ours" if critic == "privileged" else
                                                                    "ours (critic multimodal)")
    else:
        with pytest.raises(ValueError, match="612813e"):
            tacrl.read_config(str(tmp_path))
        assert "q_norm" in runs.method_of(runs.read_config(str(tmp_path)))


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
    assert set(runs.fam_of(run)) == expected


def test_an_ablation_in_numbers_has_a_row_a_setting_over_its_seeds():
    """Figs. 9-11 in numbers: each setting's cells are over its seeds, seed by seed where said; a run that never
    reached its final range says so; one setting alone is no comparison."""
    def run(obs, seed, e_r_most, trained, sr):
        cfg = {**dataclasses.asdict(tacrl.Config()), "task": "gear", "obs": obs, "curriculum": "ex10", "seed": seed,
               "stop_held": 0, "train_episodes": 200}
        e_r = np.minimum(np.arange(200) * 0.25, e_r_most)           # mm, reaches 20 at episode 81 where it may
        m = {"episode": np.arange(1, 201), "e_r_mm": e_r, "success": np.r_[np.zeros(150), np.ones(50) * trained]}
        rows = [{"error_mm": x, "success_rate": sr * x / 20, "completion_time_s": [4.0, 1.0]} for x in runs.LEVELS]
        return {"cfg": cfg, "m": m, "eval": {"rows": rows}, "dir": f"runs/{obs}-s{seed}"}
    made = [run("pt", 0, 5.0, 0.0, 0.0), run("pt", 1, 7.0, 1.0, 0.2),
            run("ts-ptv", 0, 20.0, 1.0, 1.0), run("ts-ptv", 1, 20.0, 1.0, 0.9), run("ts-ptv", 2, 20.0, 1.0, 0.7)]
    table = results.ablation_table(made, "gear", "obs")
    assert len(table) == 2 + 2 and results.ablation_table(made[:2], "gear", "obs") == []
    pt, ptv = ([c.strip() for c in row.strip("|").split("|")] for row in table[2:])
    number = lambda cell: [float(x) for x in re.findall(r"[\d.]+", cell)]      # noqa: E731  (mean, lo, hi)
    assert pt[0] == "P-T" and pt[1:3] == ["2", "never / never"] and number(pt[3]) == [6.0, 5.0, 7.0]  # E_r at the end
    assert number(pt[5]) == [0.5, 0.0, 1.0] and number(pt[6]) == [0.1, 0.0, 0.2]       # every resample of 2 seeds
    assert ptv[0] == "Time-series P-T-V" and ptv[1:3] == ["3", "81 / 81 / 81"] and number(ptv[4]) == [20.0]
    mean, lo, hi = number(ptv[6])
    assert mean == pytest.approx(0.87, abs=0.005) and 0.70 <= lo < mean < hi <= 1.00 and ptv[7] == "4.00"
    assert number(ptv[8]) == pytest.approx([0.22, 0.43, 0.65, 0.87], abs=0.005)
    assert results.ablation_table(made, "peg", "obs") == [] and results.ablation_table(made, "gear", "roi") == []
    one = [c.strip() for c in results.ablation_table(made[1:4], "gear", "obs")[2].strip("|").split("|")]
    assert one[0] == "P-T" and one[1] == "1" and one[5:7] == ["1.00", "0.20"]   # a setting of one seed: no spread


def test_a_planned_run_is_counted_for_its_own_experiment_alone():
    """The ROI ablation's task-attention run and the curriculum ablation's adaptive run share a name at two
    budgets (200 and 300 episodes): a finished run counts for the experiment whose budget it trained."""
    import sweep
    run = {"dir": "results/gear-roi/gear-ts-ptv-adaptive-s0", "m": {"episode": list(range(1, 201))},
           "cfg": {**dataclasses.asdict(tacrl.Config()), "task": "gear", "train_episodes": 200, "stop_held": 0}}
    plan = lambda exp: [sweep.config_of([*row, "--seed", "0"]) for row in sweep.EXPERIMENTS[exp]]    # noqa: E731
    assert sum(runs.is_planned(run, p) for p in plan("gear-roi")) == 1
    assert sum(runs.is_planned(run, p) for p in plan("gear-curriculum")) == 0
    unfinished = {**run, "m": {"episode": list(range(1, 150))}}
    assert sum(runs.is_planned(unfinished, p) for p in plan("gear-roi")) == 0


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


def test_the_readme_families_table_shows_the_default_and_the_robust_option_alone():
    import sim
    old = runs.view_of({**dataclasses.asdict(tacrl.Config()), "randomize": "light", "image_norm": "image"})
    by = lambda sr: {"seeds": len(sr), "train": sr, **{f: sr for f in sim.FAMILIES}}    # noqa: E731
    families = {("peg", "task attention"): by([1.0, 0.9]), ("peg", runs.OPTION_VIEW): by([0.95]), ("peg", old): by([0.5])}
    rows = [[c.strip() for c in r.strip("|").split("|")] for r in scenes.readme_families(families)[2:]]
    assert [r[:3] for r in rows] == [["peg, task attention", "2", "0.95 (0.90)"], ["peg, robust option", "1",
                                                                                  "0.95 (0.95)"]]
    assert "tilt_deg 1.0" in runs.OPTION_VIEW and "mixed" in runs.OPTION_VIEW


def test_the_papers_order_holds_only_where_each_interval_lies_above_the_next():
    mm = lambda **srs: {k + runs.MULTIMODAL: np.array(v) for k, v in srs.items()}   # noqa: E731
    apart = mm(ours=[0.9, 0.95, 1.0], keypoint=[0.6, 0.65, 0.7], visual=[0.0, 0.05, 0.1], vanilla=[0.0, 0.0, 0.1])
    pairs, missing = results.order(apart)
    assert len(pairs) == 5 and {v for *_, v in pairs} == {"above"} and not missing
    pairs, _ = results.order(dict(apart, **mm(keypoint=[0.6, 0.65, 0.95])))
    assert ("ours", "keypoint", "on the mean only") in pairs
    pairs, missing = results.order(mm(ours=[0.3, 0.4], keypoint=[0.5, 0.6]))
    assert pairs == [("ours", "keypoint", "not above")] and missing == ["visual", "vanilla"]
    assert [results.above(a, b) for a, b in (([0.9, 1.0], [0.1, 0.2]), ([0.5, 0.9], [0.4, 0.6]), ([0.1], [0.2]))] == \
        ["above", "on the mean only", "not above"]
    for srs in (apart, mm(ours=[0.3, 0.4], keypoint=[0.5, 0.6]), {}):                # one sentence, whatever was run
        assert results.ordering_sentence(srs) and "\n" not in results.ordering_sentence(srs)


def test_the_report_calls_no_setting_the_papers_unless_it_is():
    """Table 1 in full and in the README, its order sentence and the README's findings, made of runs of every learned
    method with privileged and with multimodal critics: a method or critics cell, and a sentence before the paper's
    own numbers, never calls a setting of ours the paper's; the paper is named only for its own numbers."""
    def run(changes, sr):
        cfg = {**dataclasses.asdict(tacrl.Config()), "train_episodes": 200, "stop_held": 0, **changes}
        row = {"error_mm": 20.0, "success_rate": sr, "completion_time_s": [5.0, 1.0], "cumulative_reward": [50.0, 1.0],
               **{f"contact_force_{a}_N": [1.0, 0.1] for a in "xyz"}}
        return {"cfg": cfg, "m": {"episode": list(range(1, 201))}, "eval": {"rows": [row]}, "dir": "runs/x"}
    made = [run({**method, "critic": critic, "seed": s}, 0.5 + 0.1 * s) for s in range(3)
            for critic in ("privileged", "multimodal")
            for method in ({}, {"vanilla": True}, {"obs": "v"}, {"obs": "ts-ptk"})]
    ts = {**made[0]["eval"]["rows"][0], "episodes": 20}
    full, readme, srs = results.table1(made, ts)
    for table, paper_column in ((full, 7), (readme, 4)):
        rows = [[c.strip() for c in r.strip("|").split("|")] for r in table if r.startswith("| ") and "---" not in r]
        header, rows = rows[0], rows[1:]
        assert header[paper_column].startswith("paper") and not any("paper" in h for h in header[:paper_column])
        assert len(rows) == 9 and sum("multimodal" in r[1] for r in rows) == 4
        for r in rows:
            assert not any("paper" in c for c in r[:paper_column]), r            # no setting is called the paper's
    sentence = results.ordering_sentence(srs)
    assert "paper" not in sentence.split("The paper's order")[0]
    for line in results.findings(made, srs, ts, {}):
        for part in line.split(";"):                       # each clause: ours named as ours, the paper for its numbers
            assert "paper's critics" not in part and (
                "paper" not in part or re.search(r"the paper's [\d.-]|the paper's every|the paper's about", part)), part
    labels = [*results.TABLE1_ROWS.values(), *results.CRITICS.values(), *runs.VIEWS.values(), *runs.OBS_NAMES.values()]
    assert not [x for x in labels if "paper" in x]


def test_the_leave_one_out_has_a_table_of_its_own_named_by_the_part_left_out():
    import sim
    by = lambda sr: {"seeds": len(sr), "train": sr, **{f: sr for f in sim.FAMILIES}}    # noqa: E731
    view = {out: v for v, out in runs.LOO_VIEWS.items()}
    no_tilt, no_light = view["--tilt-deg"], view["light"]
    families = {("peg", "task attention"): by([1.0]), ("peg", runs.OPTION_VIEW): by([0.95, 1.0]),
                ("peg", no_tilt): by([0.5]), ("peg", no_light): by([0.25])}
    md = scenes.family_table(families, episodes=20)
    split = next(i for i, line in enumerate(md) if line.startswith("What each part"))
    main = [r.split(" | ")[1] for r in md[:split] if r.startswith("| peg")]
    assert main == ["task attention", runs.OPTION_VIEW]
    loo = [r.split(" | ")[1:4] for r in md[split:] if r.startswith("| peg")]
    assert loo == [["nothing (the option)", "2", "0.97 (0.95-1.00)"], ["`light`", "1", "0.25"],
                   ["`--tilt-deg`", "1", "0.50"]]                                   # the option first, then as planned
    alone = scenes.family_table({("peg", no_light): by([0.25])}, episodes=20)          # a run of it, reported alone
    assert [r.split(" | ")[1] for r in alone if r.startswith("| peg")] == ["`light`"]


def _robust_run(root, name, task, seed, minutes, episodes, validation=None, robust=True):
    """A finished run dir as the archive keeps it: config.json, metrics.csv and eval.json."""
    import json
    d = root / name
    d.mkdir(parents=True)
    argv = ["--task", task, "--seed", str(seed)] + (["--robust"] if robust else [])
    cfg = dataclasses.asdict(tacrl.parse_args(argv + ["--run-dir", str(d)]))
    (d / "config.json").write_text(json.dumps(cfg))
    (d / "metrics.csv").write_text("episode,return,success,sr15,e_r_mm,ex_r_mm,elapsed_s\n1,0,0,0,0,2,1\n")
    row = {"error_mm": 20.0, "success_rate": 1.0, "episodes": 20}
    (d / "eval.json").write_text(json.dumps({"train_episodes": episodes, "train_minutes": minutes, "rows": [row],
                                             "world": 22, **({"validation": validation} if validation else {})}))


def test_the_robust_runs_table_shows_where_each_seed_first_held_and_its_time_against_the_quickstarts(tmp_path):
    import robust
    fams = tacrl.parse_args(["--robust"]).families
    fail = {"episode": 60, "train": 20, **{f: 10 for f in fams}, "calib": 7}
    looked = {"episode": 90, "train": 19, **{f: 9 for f in fams}}           # a first look that passed, then 30 each
    unconfirmed = {**looked, "confirm": {**{f: 30 for f in fams}, "mixed": 26}}
    hold = {**looked, "episode": 120, "confirm": {f: 27 for f in fams}}
    _robust_run(tmp_path / "robust-flag", "peg-s0", "peg", 0, 40.0, 120,
                [{"episode": 30, "train": 15}, fail, unconfirmed, hold])
    _robust_run(tmp_path / "robust-flag", "peg-s1", "peg", 1, 60.0, 600, [fail])
    _robust_run(tmp_path / "robust-flag", "peg-s2", "peg", 2, 50.0, 90, [looked])    # stopped by a first look alone
    for s, minutes in enumerate((10.0, 30.0, 20.0)):
        _robust_run(tmp_path / "quickstart", f"peg-{s}", "peg", s, minutes, 150, robust=False)
    (tmp_path / "robust-flag" / "bench-before.txt").write_text("ts-ptv critics privileged: median  49.4 updates/s\n")
    md = robust.flag_table(f"{tmp_path}/robust-flag/*", f"{tmp_path}/quickstart/*")
    rows = {r.split("|")[2].strip(): [c.strip() for c in r.split("|")[1:-1]] for r in md.splitlines()
            if r.startswith("| peg |")}
    assert rows["0"][2:5] == ["120", "yes", "120"]
    assert [x.strip() for x in rows["0"][5].split(";")] == ["30: train 15/20", "60: calib 7/10", "90: mixed 26/30"]
    assert rows["1"][2:5] == ["600", "no", "-"]
    assert rows["2"][2:5] == ["90", "yes", "-"] and "unconfirmed" in rows["2"][5]
    ratio = next(r for r in md.splitlines() if r.startswith("| peg (3 and 3 seeds)"))
    assert [c.strip() for c in ratio.split("|")[2:5]] == ["50.0", "20.0", "2.5"] and "49.4" in md
    said = robust.readme_time(f"{tmp_path}/robust-flag/*", f"{tmp_path}/quickstart/*")   # the README's sentence
    assert "seeds 0, 1, 2 trained 120, 600, 90 episodes in 40, 60, 50 min" in said and "median of 20 min" in said
    assert "49.4" in said


def test_a_run_a_first_look_stopped_is_shown_beside_its_held_out_scenes(tmp_path):
    import json
    import robust
    fams = tacrl.parse_args(["--robust"]).families
    _robust_run(tmp_path / "first", "gear-s0", "gear", 0, 70.0, 360, [{"episode": 360, "train": 20,
                                                                       **{f: 10 for f in fams}, "colour": 9}])
    d = tmp_path / "first" / "gear-s0"
    (d / "eval-ctx-mixed-test.json").write_text(json.dumps({"rows": [{"error_mm": 20.0, "success_rate": 0.6}]}))
    (d / "eval-scenes-mixed.json").write_text(json.dumps({"rates": [1.0, 1 / 3, 2 / 3, 0.0]}))
    rows = {r.split("|")[4].strip(): [c.strip() for c in r.split("|")[1:-1]]
            for r in robust.first_look_table(f"{tmp_path}/first/*").splitlines() if r.startswith("| gear |")}
    assert list(rows) == list(fams)
    assert rows["mixed"][2:] == ["360", "mixed", "10/10", "0.60", "0.50 / 0.50"]
    assert rows["colour"][4:] == ["9/10", "-", "-"]
