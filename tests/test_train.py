"""Algorithm 1 end to end in a tiny configuration (8 episodes of at most 15 steps, 2 updates each):
one run killed in the middle of episode 5's updates and resumed, which must come out as the same run
uninterrupted, serves the tests of what a run leaves behind; then its policy's evaluation, extending
it, the archive and the report made from it."""
import csv
import json
import os
import shutil
import sys

import numpy as np
import pytest
import torch

import cli
import evaluate
import policy
import pages
import report
import results
import rundir
import runs
import scenes
import contexts
import scene
import sim
import tacrl

TINY = ["--task", "peg", "--error-mm", "1", "--train-episodes", "8", "--warmup", "1", "--updates", "2",
        "--batch", "8", "--episodes", "1", "--eval-levels", "1", "--buffer", "40", "--threads", "1"]
# (--threads 1: the same numbers as 2, and lighter beside the other test worker)
SHORT = 9            # steps an episode, not 120: the untrained policy runs every one to the limit, and
                     # TINY's 40-transition ring wraps in mid-episode
TIMES = ("env_s", "update_s", "elapsed_s")


def metrics(run_dir):
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        return list(csv.DictReader(f))


try:                                                     # the `track` extra, as --track checks for it
    import torch.utils.tensorboard  # noqa: F401
    HAS_TENSORBOARD = True
except ImportError:
    HAS_TENSORBOARD = False


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The same run never stopped, logged to TensorBoard as well (--track) where the `track` extra is installed."""
    run_dir = str(tmp_path_factory.mktemp("train") / "whole")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sim, "MAX_STEPS", SHORT)
        track = ["--track"] if HAS_TENSORBOARD else []
        tacrl.train(tacrl.parse_args(TINY + ["--run-dir", run_dir] + track), log=lambda *_: None)
    return {"dir": run_dir, "rows": metrics(run_dir)}


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    run_dir = str(tmp_path_factory.mktemp("train") / "run")
    first, second, calls = [], [], []
    real_update = policy.SAC.update

    def killed_in_episode_5(sac, batch):      # updates run from episode 2, two an episode: call 7 is in episode 5
        calls.append(np.any(batch[1]))       # (not the start-up probe's calls, whose actions are all zero)
        if sum(calls) == 7:
            raise KeyboardInterrupt            # as a kill: episode 7's replay file is written, its checkpoint not
        return real_update(sac, batch)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sim, "MAX_STEPS", SHORT)
        mp.setattr(policy.SAC, "update", killed_in_episode_5)
        with pytest.raises(KeyboardInterrupt, match="--resume"):
            tacrl.train(tacrl.parse_args(TINY + ["--run-dir", run_dir]), log=first.append)
        replay_at_kill = sorted(os.listdir(os.path.join(run_dir, "replay")))
        rows_at_kill = metrics(run_dir)
        mp.setattr(policy.SAC, "update", real_update)
        tacrl.train(tacrl.parse_args(["--resume", run_dir]), log=second.append)
    return {"dir": run_dir, "first": first, "second": second, "replay_at_kill": replay_at_kill,
            "rows_at_kill": rows_at_kill, "rows": metrics(run_dir),
            "eval": json.loads(open(os.path.join(run_dir, "eval.json")).read())}


def test_a_run_killed_and_resumed_is_the_same_run_as_one_never_stopped(tiny_run, uninterrupted):
    # each episode is simulated in a new world and the replay buffer is rebuilt slot by slot, so the
    # resumed run repeats the uninterrupted one to the last digit (and two runs of a seed are the same)
    strip = lambda rows: [{k: v for k, v in r.items() if k not in TIMES} for r in rows]   # noqa: E731
    assert len(uninterrupted["rows"]) == 8 and any(float(r["q_loss"]) > 0 for r in uninterrupted["rows"])
    assert strip(tiny_run["rows"]) == strip(uninterrupted["rows"])     # (and --track changes nothing)


def test_a_resumed_runs_first_episode_counts_its_own_time_not_the_runs(tiny_run):
    rows, k = tiny_run["rows"], len(tiny_run["rows_at_kill"])      # row k: the first episode after the resume
    assert float(rows[k]["env_s"]) < float(rows[k - 1]["elapsed_s"]) and float(rows[k]["env_s"]) < 60


@pytest.mark.skipif(not HAS_TENSORBOARD, reason="the `track` extra (tensorboard) is not installed")
def test_track_writes_what_tensorboard_reads(uninterrupted):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    ea = EventAccumulator(os.path.join(uninterrupted["dir"], "tb"), size_guidance={"scalars": 0, "images": 0})
    ea.Reload()
    rows = uninterrupted["rows"]
    assert [(e.step, e.value) for e in ea.Scalars("charts/return")] == \
        [(int(r["episode"]), pytest.approx(float(r["return"]))) for r in rows]
    assert [e.step for e in ea.Scalars("losses/q_loss")] == [int(r["episode"]) for r in rows if r["q_loss"] != "nan"]
    assert {"charts/e_r_mm", "charts/sr15", "losses/alpha", "time/update_s"} <= set(ea.Tags()["scalars"])
    (image,) = ea.Images("obs/task_attention")                    # episode 1's, every TB_IMAGE_EVERY episodes
    assert image.step == 1 and (image.width, image.height) == (sim.IMG, sim.IMG)
    assert image.encoded_image_string.startswith(b"\x89PNG")


def test_track_without_tensorboard_is_one_line_naming_the_extra(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "torch.utils.tensorboard", None)        # as if the extra were not installed
    assert tacrl.main(["--task", "peg", "--track"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--track" in err and ".[track]" in err and not os.path.exists("runs")


def test_start_up_lines_give_the_config_by_group_and_the_parameter_counts(tiny_run):
    config, params = tiny_run["first"][0].split("\n"), tiny_run["first"][1]
    assert config[0] == "config:" and all(len(x) <= 110 for x in config)
    words = " ".join(config).split()
    for title in tacrl.Config.GROUPS:                           # each group's title once, its flags as typed
        assert " ".join(config).count(title.split(" (")[0]) == 1, title
    for flag, value in zip(TINY[::2], TINY[1::2]):
        assert words[words.index(flag) + 1] == value, flag
    assert params.startswith("parameters: actor ") and "critics " in params


def test_a_kill_loses_only_the_episode_in_flight(tiny_run):
    assert [int(r["episode"]) for r in tiny_run["rows_at_kill"]] == list(range(1, 5))
    assert tiny_run["replay_at_kill"][-1] == "ep_000004.npz"       # the episode in flight's is not written
    assert any(x.startswith(f"resumed {tiny_run['dir']} at episode 4 of 8: ") for x in tiny_run["second"])
    episodes = [x.split()[1] for x in tiny_run["second"] if x.startswith("ep ")]
    assert episodes == [f"{k}/8" for k in range(5, 9)]
    assert [int(x["episode"]) for x in tiny_run["rows"]] == list(range(1, 9))


def test_a_finished_run_leaves_every_file(tiny_run):
    for f in ("config.json", "ckpt.pt", "metrics.csv", "policy.pt", "curves.png", "eval.json"):
        assert os.path.getsize(os.path.join(tiny_run["dir"], f)) > 0, f


def test_updates_start_after_the_warmup(tiny_run):
    assert [int(x["updates"]) for x in tiny_run["rows"]] == [0] + [2] * 7


def test_the_replay_on_disk_is_what_the_ring_buffer_holds(tiny_run):
    steps = [int(x["steps"]) for x in tiny_run["rows"]]
    keep = next(i for i in range(8, -1, -1) if sum(steps[i:]) >= 40 or i == 0)     # newest that fill 40
    kept = sorted(os.listdir(os.path.join(tiny_run["dir"], "replay")))
    assert kept == [f"ep_{i + 1:06d}.npz" for i in range(keep, 8)], (steps, kept)


def test_a_run_dir_that_holds_a_run_is_not_started_over(tiny_run, capsys, monkeypatch):
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)          # (TINY's 40-transition buffer holds a short episode)
    assert tacrl.main(TINY + ["--run-dir", tiny_run["dir"]]) == 2
    assert "--resume" in capsys.readouterr().err


def test_evaluating_policy_pt_repeats_eval_json(tiny_run, tmp_path, monkeypatch):
    # training evaluates in a new simulator, so --eval in a fresh one repeats it to the last digit
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)          # as the run was evaluated
    ev = tiny_run["eval"]
    assert [row["error_mm"] for row in ev["rows"]] == [1.0] and ev["eval_seed"] != ev["seed"]
    again = tmp_path / "again.json"
    assert tacrl.main(["--task", "peg", "--eval", os.path.join(tiny_run["dir"], "policy.pt"), "--error-mm", "1",
                       "--episodes", "1", "--json", str(again)]) == 0
    keys = ("success_rate", "cumulative_reward", "contact_force_x_N", "contact_force_y_N", "contact_force_z_N")
    assert {k: ev["rows"][0][k] for k in keys} == {k: json.loads(again.read_text())[k] for k in keys}


def test_the_evaluation_after_training_shows_each_episode_and_its_eta_counts_the_levels_to_come(tiny_run):
    evals = [x for x in tiny_run["second"] if x.startswith("eval ")]
    assert len(evals) == 1 and evals[0].startswith("eval 1 mm  episode 1/1 ") and " ETA " in evals[0]
    # and the training's ETA counts the evaluation: every level's episodes that this process plays, each as long as
    # the last episodes' env time
    run = rundir.Run.__new__(rundir.Run)
    run.cfg, run.episode, run.laps, run.update_s, run.probe_update = tacrl.Config(train_episodes=10, warmup=0), 10, \
        {"env": [9.0] * 5 + [2.0] * rundir.EVAL_LIKE}, [1.0], 1.0
    run.eval_episodes = 40
    assert run.eta() == pytest.approx(40 * 2.0)


def test_a_checkpoint_is_a_policy_too_and_a_policy_takes_a_batch(tiny_run, monkeypatch):
    # a run's ckpt.pt plays what its policy.pt plays (both of its last episode), as tacrl.load_policy and --eval read
    # it; and a vector env's batch of observations gives each its own action
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    pi, ck = (tacrl.load_policy(os.path.join(tiny_run["dir"], f)) for f in ("policy.pt", "ckpt.pt"))
    assert ck.meta == pi.meta
    with evaluate.eval_env("peg", pi, e_r_mm=1.0) as env:
        obs = [env.reset(seed=s)[0] for s in (0, 1, 2)]
    batch = {k: np.stack([o[k] for o in obs]) for k in obs[0]}
    assert np.array_equal(pi(obs[1]), ck(obs[1]))
    assert pi(batch).shape == (3, 6) and np.allclose(pi(batch), np.stack([pi(o) for o in obs]), atol=1e-6)
    with pytest.raises(ValueError, match="cannot load"):
        evaluate.load_policy(os.path.join(tiny_run["dir"], "ckpt.pt"))     # without tacrl's reader of checkpoints


def test_a_worker_process_plays_every_other_episode_and_the_row_is_the_same(monkeypatch):
    # every episode is a fresh world drawn from its seed alone, so who plays it changes nothing: the worker's episode
    # is this process's to the last digit, and an evaluation with a worker gives it the odd episodes. The policy: a new
    # agent's, its residual scaled down so that the hand-designed part inserts
    torch.manual_seed(0)                            # (its weights, whatever tests ran before in this process)
    sac = tacrl.make_sac(tacrl.parse_args(["--task", "peg", "--threads", "1"]))
    with torch.no_grad():
        sac.actor.net[-1].weight.mul_(0.01)
    pi = evaluate.TrainedPolicy(evaluate.policy_file(sac, {"task": "peg", "obs": "ts-ptv", "roi": "task",
                                                           "vanilla": False, "ex_r": 0.001, "e_r_max": 0.02}))
    seeds = [evaluate.episode_seed(5, k) for k in range(3)]
    with evaluate.eval_env("peg", pi) as env, evaluate.Worker() as worker:   # (its imports overlap this episode)
        here = evaluate.play(env, pi, seeds[1])
        asked, there, results = [], [], worker.results
        monkeypatch.setattr(evaluate, "play", lambda env, act, seed, video=None: asked.append(seed) or here)
        monkeypatch.setattr(worker, "results", lambda: there.extend(results()) or there)
        row = evaluate.evaluate(env, pi, 3, 5, log=lambda *_: None, worker=worker)
    assert asked == [seeds[0], seeds[2]] and len(there) == 1             # this process the even ones, the worker 1
    assert there[0][0] == here[0] and there[0][1:2] == here[1:2] and np.array_equal(there[0][2], here[2])
    assert there[0][3] == here[3] and row["success_rate"] == 1.0 == here[0]    # (an episode that ended early)


def test_validation_plays_the_greedy_action_of_the_agent_it_copies():
    cfg = tacrl.parse_args(["--task", "peg", "--threads", "1"])
    sac = tacrl.make_sac(cfg)
    before = torch.random.get_rng_state()
    pi = evaluate.TrainedPolicy(evaluate.policy_file(sac, {"obs": cfg.obs}))
    assert torch.equal(torch.random.get_rng_state(), before)     # training goes on as if it had not validated
    with tacrl.make_env(cfg, e_r=0.001) as env:
        obs, _ = env.reset(seed=3)
    assert np.array_equal(pi(obs), sac.act(obs, deterministic=True))


def test_a_policy_is_evaluated_with_the_exploration_range_it_trained_with(tiny_run, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    pol = str(tmp_path / "policy.pt")
    d = torch.load(os.path.join(tiny_run["dir"], "policy.pt"), weights_only=True)
    assert d["ex_r"] <= 0.002 and tiny_run["eval"]["rows"][0]["ex_r_mm"] == 2.0     # where it ended, floored at 2 mm
    assert d["e_r_max"] == 0.02              # and the env it saw: ROI and X_i for 20 mm, the least there is
    assert d["tilt"] == 0.0                  # a level board's stiffness about x and y (no --tilt-deg)
    d["ex_r"] = 0.015                        # as if it had ended at 15 mm: evaluated at 0 mm, Ex_r stays 15
    d["tilt"] = 0.01                         # and trained with room for a tilted board: evaluated with it
    torch.save(d, pol)
    with evaluate.eval_env("peg", evaluate.load_policy(pol)) as env:
        assert env.tilt == 0.01
    out = tmp_path / "row.json"
    assert tacrl.main(["--task", "peg", "--eval", pol, "--error-mm", "0", "--episodes", "1", "--json", str(out)]) == 0
    assert "TA-MRP peg 0mm" in capsys.readouterr().out
    row = json.loads(out.read_text())
    assert row["episodes"] == 1 and row["error_mm"] == 0 and row["ex_r_mm"] == 15.0


@pytest.mark.parametrize("args, flag", [(["--task", "gear"], "--task"), (["--task", "peg", "--roi", "200"], "--roi")])
def test_a_policy_is_not_evaluated_in_another_task_or_view(tiny_run, capsys, args, flag):
    assert tacrl.main(args + ["--eval", os.path.join(tiny_run["dir"], "policy.pt")]) == 2
    err = capsys.readouterr().err
    assert flag in err and err.count("\n") == 1


def test_archive_keeps_what_the_report_reads_and_skips_unfinished_runs(tiny_run, tmp_path):
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    for f in ("config.json", "metrics.csv"):
        shutil.copy(os.path.join(tiny_run["dir"], f), unfinished / f)
    lines = []
    archive = tmp_path / "results"
    assert runs.archive_runs(f"{tiny_run['dir']},{unfinished}", dest=str(archive), log=lines.append) == \
        [str(archive / "run")]
    assert sorted(os.listdir(archive / "run")) == ["config.json", "curves.png", "eval.json", "metrics.csv", "policy.pt"]
    assert any(str(unfinished) in x and "not finished" in x for x in lines)
    assert cli.command("report", lambda: report.main([str(unfinished), "--archive"])) == 2


def cells(block, first):
    """The cells of a block's table row whose first cell is `first`."""
    row = next(ln for ln in block.splitlines() if ln.startswith(f"| {first} |"))
    return [c.strip() for c in row.strip("|").split("|")]


def test_report_fills_the_pages_blocks_from_an_archive(tiny_run, tmp_path, monkeypatch):
    monkeypatch.setattr(results, "QUICKSTART_RUNS", str(tmp_path / "none" / "*"))    # no reference runs, no SB3 runs:
    monkeypatch.setattr(results, "SB3_RUNS", str(tmp_path / "none" / "*.json"))      # their blocks are left as they are
    archive = tmp_path / "results"
    runs.archive_runs(tiny_run["dir"], dest=str(archive), log=lambda *_: None)
    docs = tmp_path / "docs"
    docs.mkdir()
    row = {"success_rate": 0.5, "completion_time_s": [10.0, 1.0], "contact_force_x_N": [1.0, 0.0],
           "contact_force_y_N": [1.0, 0.0], "contact_force_z_N": [1.0, 0.0], "cumulative_reward": [1.0, 0.0],
           "episodes": 20}      # the two-step row's cache: evaluating the baseline takes a minute
    runs.write_world_cache(str(docs / "two-step-peg-20mm.json"), sim.WORLD, row)
    page = "# A page\n\nProse.\n\n" + "".join(f"<!-- report: {b} -->\ntyped\n<!-- end -->\n\n" for b in results.BLOCKS)
    (docs / "all.md").write_text(page + "The end.\n")
    readme = tmp_path / "README.md"
    readme.write_text("# x\n\n<!-- report: readme-table1 -->\n<!-- end -->\n\n<!-- report: code-map -->\n<!-- end -->\n")
    argv = [str(archive / "*"), "--out", str(docs), "--readme", str(readme)]
    assert cli.command("report", lambda: report.main(argv)) == 0
    blocks = pages.blocks((docs / "all.md").read_text())
    assert (docs / "all.md").read_text().startswith("# A page\n\nProse.\n") and "The end." in (docs / "all.md").read_text()
    assert blocks["quickstart"] == blocks["sb3"] == "typed\n"                  # nothing made of them: as they were
    two_step = cells(blocks["table1"], "two-step (visual servo, spiral search)")
    assert two_step[3:5] == ["0.50", "10.00 +- 1.00"]                           # SR and CT, the cache's
    assert "not run in this world" in cells(blocks["table1"], "ours (TA-MRP + adaptive curriculum)")   # not 200 eps
    in_readme = pages.blocks(readme.read_text())
    assert in_readme["readme-table1"] == blocks["readme-table1"] != "typed\n"   # one table in two pages
    lines = sum(1 for _ in open(os.path.join(os.path.dirname(tacrl.__file__), "tacrl.py")))
    assert cells(in_readme["code-map"], "`tacrl.py`")[1] == str(lines)         # the code map's sizes, counted
    other = archive / "other-world"                      # a run of another world: refused, nothing written
    shutil.copytree(archive / "run", other)
    (other / "eval.json").write_text(json.dumps({**json.loads((other / "eval.json").read_text()), "world": None}))
    before = (docs / "all.md").read_text()
    assert cli.command("report", lambda: report.main(argv)) == 2
    assert (docs / "all.md").read_text() == before


def test_a_pages_blocks_are_made_anew_and_the_rest_kept_and_a_stale_one_named(tmp_path):
    page = tmp_path / "p.md"
    page.write_text("# x\n\n<!-- report: a -->\nold\n<!-- end -->\n\nkept\n\n<!-- report: b -->\n<!-- end -->\n")
    assert pages.fill(str(page), {"a": "| 1 |", "c": "not here"}, log=lambda *_: None) == ["a"]
    assert page.read_text() == "# x\n\n<!-- report: a -->\n| 1 |\n<!-- end -->\n\nkept\n\n<!-- report: b -->\n<!-- end -->\n"
    assert pages.stale(str(page), {"a": "| 1 |"}) == [] and pages.stale(str(page), {"a": "| 2 |", "b": "x"}) == ["a", "b"]
    long = "word " * 60                                          # prose wraps at 120, a table's row does not
    assert all(len(x) <= 120 for x in pages.wrap(long).split("\n")) and pages.wrap("|" + long) == "|" + long


def test_table2_rows_are_evaluated_once_per_world_and_context(tiny_run, tmp_path, monkeypatch):
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    d = tmp_path / "run"
    shutil.copytree(tiny_run["dir"], d)
    run, said = runs.load_run(str(d)), []
    train = runs.eval_cached(run, "train", levels=(1.0,), episodes=1, log=said.append)
    assert not said and train == run["eval"]["rows"]            # the training context's rows: eval.json's
    loc = runs.eval_cached(run, "loc-2", levels=(1.0,), episodes=1, log=said.append)
    assert len(said) == 1 and runs.eval_cached(run, "loc-2", levels=(1.0,), episodes=1, log=said.append) == loc
    cache = d / "eval-ctx-loc-2.json"                             # the cache report.py --contexts fills too
    assert json.loads(cache.read_text())["world"] == sim.WORLD and len(said) == 1
    cache.write_text(json.dumps({**json.loads(cache.read_text()), "world": sim.WORLD - 1}))  # another world's rows
    runs.eval_cached(run, "loc-2", levels=(1.0,), episodes=1, log=said.append)
    assert len(said) == 2 and json.loads(cache.read_text())["world"] == sim.WORLD       # evaluated again
    old = {**run, "eval": {**run["eval"], "world": None}}          # a run of an older world: never evaluated here
    with pytest.raises(runs.ArgError, match="made in world unversioned"):
        runs.eval_cached(old, "loc-2", levels=(1.0,), episodes=1, log=said.append)


def test_compare_lists_finished_and_unfinished_runs_and_refuses_two_worlds(tiny_run, tmp_path):
    unfinished = tmp_path / "runs" / "unfinished"
    unfinished.mkdir(parents=True)
    shutil.copy(os.path.join(tiny_run["dir"], "metrics.csv"), unfinished / "metrics.csv")
    cfg = runs.read_json(os.path.join(tiny_run["dir"], "config.json"))
    other_task = {"peg": "gear", "gear": "peg"}[cfg["task"]]             # the same settings on the other task
    (unfinished / "config.json").write_text(json.dumps({**cfg, "task": other_task}))
    docs = tmp_path / "docs"
    assert cli.command("report", lambda: report.main([f"{tiny_run['dir']},{unfinished}", "--compare", "cmp",
                                                         "--out", str(docs)])) == 0
    rows = [ln for ln in (docs / "cmp.md").read_text().splitlines() if ln.startswith("|")][2:]   # under the header
    assert len(rows) == 2 and sum("unfinished" in r for r in rows) == 1 and (docs / "cmp.png").stat().st_size > 0
    assert sorted(r.split(",")[0] for r in rows) == sorted(f"| {t}" for t in (cfg["task"], other_task))  # apart
    other = tmp_path / "runs" / "other-world"
    shutil.copytree(tiny_run["dir"], other)
    ev = json.loads((other / "eval.json").read_text())
    (other / "eval.json").write_text(json.dumps({**ev, "world": ev["world"] - 1}))
    assert cli.command("report", lambda: report.main([f"{tiny_run['dir']},{other}", "--compare", "cmp",
                                                         "--out", str(docs)])) == 2
    assert cli.command("report", lambda: report.main([tiny_run["dir"], "--compare", "../x"])) == 2


def test_behaviour_and_view_figures(tiny_run, tmp_path, monkeypatch):
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    rec, term = results.record_episode(runs.load_run(tiny_run["dir"]), error_mm=0.0)
    assert len(rec["action"]) == len(rec["phase"]) > 0 and list(rec["phase"]) == sorted(rec["phase"])
    assert np.shape(rec["saliency"]) == np.shape(rec["image"]) == (len(rec["action"]), 80, 80)
    assert np.max(rec["saliency"]) > 0            # the lateral action depends on the image
    results.figures.plot_behaviour(rec, str(tmp_path / "behaviour.png"), "tiny")
    results.figures.plot_views("peg", ("full",), ("train", "bg-objects"), str(tmp_path / "views.png"))
    assert (tmp_path / "behaviour.png").stat().st_size > 0 and (tmp_path / "views.png").stat().st_size > 0


def test_a_finished_run_is_not_resumed_but_can_be_extended(tiny_run, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    assert tacrl.main(["--resume", tiny_run["dir"]]) == 2
    err = capsys.readouterr().err
    assert "--train-episodes" in err and err.count("\n") == 1          # how to extend it, in one line
    with monkeypatch.context() as m:                     # refused before any env is built
        m.setattr(tacrl, "make_env", None)
        assert tacrl.main(["--resume", tiny_run["dir"], "--train-episodes", "5"]) == 2
    err = capsys.readouterr().err
    assert "--train-episodes 5" in err and err.count("\n") == 1
    run_dir = str(tmp_path / "run")
    shutil.copytree(tiny_run["dir"], run_dir)
    for cached in ("eval-ctx-loc-2.json", "eval-bg-light-1mm.json"):     # evaluations of the old policy
        shutil.copy(os.path.join(run_dir, "eval.json"), os.path.join(run_dir, cached))
    archive = tmp_path / "results"
    runs.archive_runs(run_dir, dest=str(archive), log=lambda *_: None)
    archived_cfg = json.loads((archive / "run" / "config.json").read_text())
    del archived_cfg["augment"]                          # as written before that flag existed: its default
    (archive / "run" / "config.json").write_text(json.dumps(archived_cfg))
    assert tacrl.main(["--resume", run_dir, "--train-episodes", "9"]) == 0
    assert [int(r["episode"]) for r in metrics(run_dir)] == list(range(1, 10))
    assert sorted(f for f in os.listdir(run_dir) if f.startswith(("policy", "eval", "curves"))) == [
        "curves-ep8.png", "curves.png", "eval-bg-light-1mm-ep8.json", "eval-ctx-loc-2-ep8.json", "eval-ep8.json",
        "eval.json", "policy-ep8.pt", "policy.pt"]
    # archived again, the extended run replaces its earlier state: no cached evaluation of the old policy is left
    runs.archive_runs(run_dir, dest=str(archive), log=lambda *_: None)
    assert sorted(os.listdir(archive / "run")) == ["config.json", "curves.png", "eval-bg-light-1mm-ep8.json",
                                                   "eval-ctx-loc-2-ep8.json", "eval-ep8.json", "eval.json",
                                                   "metrics.csv", "policy.pt"]
    assert runs.same_run(run_dir, str(archive / "run")) == "same" and len(metrics(archive / "run")) == 9
    assert scenes.training_of(runs.load_run(run_dir)) == "seed 0: 9 episodes (first finished at 8, then trained on)"
    assert scenes.training_of(runs.load_run(tiny_run["dir"])) == "seed 0: 8 episodes"
    assert json.load(open(os.path.join(run_dir, "config.json")))["train_episodes"] == 9


@pytest.mark.parametrize("wins, stops", [([1] * 5, None), ([2], 3), ([1, 0, 2], 7)])
def test_the_stop_rule_validates_every_few_episodes_at_the_final_range_and_stops_at_a_pass(wins, stops, monkeypatch):
    # --stop-held 3: validated from the 3rd episode in a row at the final range on, every VAL_EVERY (2 here)
    # episodes; a validation that passes, with VAL_WINS (2) wins, stops the run
    monkeypatch.setattr(tacrl, "VAL_EVERY", 2)
    monkeypatch.setattr(tacrl, "VAL_WINS", 2)
    rule, lines, at = tacrl.StopRule(tacrl.Config(stop_held=3, train_episodes=12)), [], []
    for ep in range(12):
        if rule.learned(True, lambda: at.append(ep + 1) or wins[len(at) - 1], dict, lines.append, ep):
            break
    assert at == [3, 5, 7, 9, 11][:len(wins)] and ep + 1 == (stops or 12)
    assert (lines[-1] == f"stopped as learned at episode {stops} (--stop-held 0 trains all 12)") == bool(stops)
    rule.learned(False, lambda: pytest.fail("validated off the final range"), dict, lines.append, 12)   # restarts
    assert rule.held == 0
    rule.load_state_dict({"held": 4, "passes": 1})      # a checkpoint from when two passes in a row were needed
    assert rule.held == 4


def test_a_run_that_learned_stops_and_says_so(tmp_path, monkeypatch):
    # no curriculum: E_r is at its final range from the first episode, so with --stop-held 3 the greedy
    # policy is validated after episode 3, and 0 wins of 2 pass (VAL_WINS 0)
    monkeypatch.setattr(sim, "MAX_STEPS", 10)               # short episodes: the rule is tested, not learning
    monkeypatch.setattr(tacrl, "VAL_EPISODES", 2)
    monkeypatch.setattr(tacrl, "VAL_EVERY", 2)
    monkeypatch.setattr(tacrl, "VAL_WINS", 0)
    lines = []
    result = tacrl.train(tacrl.parse_args(TINY + ["--curriculum", "none", "--stop-held", "3", "--train-episodes", "8",
                                                  "--run-dir", str(tmp_path / "run")]), log=lines.append)
    assert result["train_episodes"] == 3 and len(rundir.read_metrics(str(tmp_path / "run"))["episode"]) == 3
    told = [x for x in lines if x.startswith(("validation", "stopped"))]
    assert len(told) == 2 and told[-1].startswith("stopped") and "episode 3 " in told[-1] + " "


def test_the_eta_counts_the_updates_still_to_come_during_the_warmup():
    # after episode 1 of 300 (a warm-up of 20; 1 s of env), before any update: 299 episodes of env, 280 with
    # an update phase as long as the probe measured (6 s)
    assert rundir.eta_seconds(1, 300, 20, [1.0], [], 6.0) == pytest.approx(299 * 1.0 + 280 * 6.0)
    # later, the update phases measured replace the probe
    assert rundir.eta_seconds(100, 300, 20, [2.0] * 100, [4.0] * 80, 6.0) == pytest.approx(200 * (2.0 + 4.0))


def test_every_context_is_evaluated_once_and_the_table_names_each(tiny_run, tmp_path, monkeypatch):
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    two = {k: contexts.CONTEXTS[k] for k in ("train", "loc-2")}
    monkeypatch.setattr(contexts, "CONTEXTS", two)        # (where the env and the report read them)
    monkeypatch.setattr(sim, "FAMILIES", ("parts",))
    out = tmp_path / "docs"
    made = scenes.make(tiny_run["dir"], str(out), levels=(1.0,), episodes=1, log=lambda *_: None)
    view = "task attention (updates 2, warmup 1, batch 8, buffer 40)"
    assert cells(made["contexts"], f"peg | {view} | loc-2")[3] == "1"       # a seed
    assert cells(made["contexts"], f"peg | {view} | train")[4] == f"{tiny_run['eval']['rows'][0]['success_rate']:.2f}"
    assert cells(made["families"], f"peg | {view}")[3] == "-"                # 20 mm: not trained at, not evaluated
    family = json.loads(open(os.path.join(tiny_run["dir"], "eval-ctx-parts-test.json")).read())
    assert family["context"] == contexts.context_key("parts:test", "peg") and family["levels"] == [20.0]
    asked = []
    real_rows = runs.context_rows
    monkeypatch.setattr(runs, "context_rows", lambda job: asked.append(job[1]) or real_rows(job))
    again = scenes.make(tiny_run["dir"], str(out), levels=(1.0,), episodes=1, log=lambda *_: None, named=False)
    assert asked == ["parts:test"] and again["families"] == made["families"] and "contexts" not in again
    monkeypatch.setattr(runs, "context_rows", real_rows)
    assert (out / "ctx-peg-bars.png").stat().st_size > 0 and (out / "ctx-peg-views.png").stat().st_size > 0
    cached = json.loads(open(os.path.join(tiny_run["dir"], "eval-ctx-loc-2.json")).read())
    assert cached["world"] == sim.WORLD and cached["context"] == repr(contexts.CONTEXTS["loc-2"])
    monkeypatch.setattr(evaluate, "evaluate_levels", lambda *a, **k: pytest.fail("evaluated again"))
    scenes.make(tiny_run["dir"], str(out), levels=(1.0,), episodes=1, log=lambda *_: None)
    # a redefined context is evaluated again
    monkeypatch.setitem(contexts.CONTEXTS, "loc-2", scene.Context(board_xy=(0.6, -0.2), board_yaw=0.3))
    with pytest.raises(pytest.fail.Exception, match="evaluated again"):
        scenes.make(tiny_run["dir"], str(out), levels=(1.0,), episodes=1, log=lambda *_: None)


def test_every_held_out_scene_of_a_family_is_played_and_its_rates_cached(tiny_run, tmp_path, monkeypatch):
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    seen, real = [], evaluate.evaluate
    monkeypatch.setattr(evaluate, "evaluate", lambda env, *a, **k: (real(env, *a, **k), seen.append(env.scene))[0])
    rates = scenes.scene_rates((tiny_run["dir"], "parts", 3, 1))
    parts = [contexts.family_context("parts", contexts.FAMILY_TEST_SEED0 + i, "peg") for i in range(3)]
    assert len(rates) == 3 and all(0 <= x <= 1 for x in rates) and seen == parts       # scene by scene, held out
    monkeypatch.setattr(evaluate, "evaluate", lambda *a, **k: pytest.fail("evaluated again"))
    assert scenes.scene_rates((tiny_run["dir"], "parts", 3, 1)) == rates
    with pytest.raises(pytest.fail.Exception):                                    # another number of scenes: anew
        scenes.scene_rates((tiny_run["dir"], "parts", 4, 1))


def test_a_run_trained_in_the_families_scenes_is_tested_on_their_held_out_seeds_alone(tiny_run, tmp_path, monkeypatch):
    # the named backgrounds are of the kinds a --randomize run has met: it is in the families' table alone
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    monkeypatch.setattr(sim, "FAMILIES", ("light",))
    run = tmp_path / "rand"
    shutil.copytree(tiny_run["dir"], run, ignore=shutil.ignore_patterns("eval-ctx-*", "replay"))
    cfg = json.loads((run / "config.json").read_text())
    (run / "config.json").write_text(json.dumps({**cfg, "randomize": "light"}))
    asked = []
    real_rows = runs.context_rows
    monkeypatch.setattr(runs, "context_rows", lambda job: asked.append(job[1]) or real_rows(job))
    made = scenes.make(str(run), str(tmp_path / "docs"), levels=(1.0,), episodes=1, log=lambda *_: None)
    assert asked == ["light:test"] and "randomize light" in made["families"] and "| loc-" not in made["contexts"]


def test_critics_diagnostics_of_a_run_and_its_compare_row(tiny_run, tmp_path, monkeypatch):
    import critics
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    run = tmp_path / "runs" / "run"
    shutil.copytree(tiny_run["dir"], run)
    assert cli.command("critics", lambda: critics.main([str(run), "--resets", "2"])) == 2
    assert cli.command("critics", lambda: critics.main([str(run), "--resets", "6", "--episodes", "1"])) == 0
    c = json.loads((run / "critics.json").read_text())
    assert set(c["probe"]["r2"]) == set(c["probe"]["r2_untrained"]) == {"x", "y", "z", "yaw"}
    assert c["probe"]["features"] == "the actor's encoder"          # tiny_run's critics are privileged
    docs = tmp_path / "docs"
    assert cli.command("report", lambda: report.main([str(run), "--compare", "cmp", "--out", str(docs)])) == 0
    row = [ln for ln in (docs / "cmp.md").read_text().splitlines() if ln.startswith("|")][2]
    assert f"{c['probe']['r2']['x']:.2f} / {c['probe']['r2']['y']:.2f}" in row


def test_soft_returns_and_the_probes_regression():
    import critics
    r, logp = np.array([1.0, 2.0, 3.0]), np.array([-1.0, -2.0, 0.0])     # logp of the next step's action
    g = critics.soft_returns(r, logp, gamma=0.5, alpha=0.1)
    assert g[2] == 3.0 and g[1] == 2.0 + 0.5 * (3.0 + 0.1 * 2.0) and g[0] == 1.0 + 0.5 * (g[1] + 0.1 * 1.0)
    rng = np.random.default_rng(0)
    x = rng.normal(size=(400, 5))
    y = np.stack([x @ rng.normal(size=5), rng.normal(size=400)], 1)      # one target linear in x, one noise
    r2 = critics.ridge_r2(x[:200], y[:200], x[200:], y[200:], lam=1e-4)
    assert r2[0] > 0.99 and r2[1] < 0.05


def test_the_papers_critics_train_a_run(tmp_path, monkeypatch):
    # --critic multimodal through Algorithm 1 (the update-time probe, the sampling, the evaluation), so that nothing
    # of it fails only in a real run
    monkeypatch.setattr(sim, "MAX_STEPS", SHORT)
    argv = ["--task", "peg", "--error-mm", "1", "--train-episodes", "3", "--warmup", "1", "--updates", "2",
            "--batch", "4", "--episodes", "1", "--eval-levels", "1", "--buffer", "40", "--threads", "1",
            "--critic", "multimodal", "--run-dir", str(tmp_path / "run")]
    result = tacrl.train(tacrl.parse_args(argv), log=lambda *_: None)
    assert result["train_episodes"] == 3 and len(result["rows"]) == 1


@pytest.mark.parametrize("state_dim,image_norm", [(7, "fixed"), (7, "image"), (0, "fixed")])
def test_a_saved_policy_keeps_its_encoders_layout(tmp_path, state_dim, image_norm):
    torch.manual_seed(0)
    sac = policy.SAC("ts-ptv", state_dim=state_dim, image_norm=image_norm)
    evaluate.save_policy(str(tmp_path / "p.pt"), sac, {"task": "peg", "obs": "ts-ptv"})
    pi = evaluate.TrainedPolicy(rundir.load_file(str(tmp_path / "p.pt")))
    rng = np.random.default_rng(0)
    obs = {"image": rng.integers(0, 256, (1, 80, 80), dtype=np.uint8), "pose_hist": rng.normal(0, 0.01, (32, 6)).astype(
        np.float32), "wrench_hist": rng.normal(0, 1, (32, 6)).astype(np.float32)}
    np.testing.assert_array_equal(pi(obs), sac.act(obs, deterministic=True))
    old = {**rundir.load_file(str(tmp_path / "p.pt")), "image_encoder": "spatial", "image_feat": 6}
    with pytest.raises(ValueError, match="critics study"):                  # a study's encoder: its tag reads it
        evaluate.TrainedPolicy(old)


@pytest.mark.parametrize("train, first, confirm, stops", [
    ([2, 2, 2], [{"reach": 1, "calib": 2}] * 3, [], None),                          # a family never passes a look
    ([1, 2, 2], [{"reach": 2, "calib": 1}, {"reach": 2, "calib": 2}], [{"reach": 4, "calib": 4}], 9),
    ([2, 2, 2], [{"reach": 2, "calib": 2}] * 3, [{"reach": 3, "calib": 4}] * 3, None),  # passes looks, never confirms
    ([2], [{"reach": 2, "calib": 2}], [{"reach": 4, "calib": 4}], 3)])
def test_with_families_the_stop_rule_asks_each_familys_training_side_and_confirms_a_pass(train, first, confirm, stops,
                                                                                          monkeypatch):
    # --randomize: validated every FAMILY_EVERY (3 here) episodes; the families only where training's scene passes
    # (VAL_WINS 2), a first look of FAMILY_EPISODES (2) each; where every family has FAMILY_WINS (2), FAMILY_CONFIRM
    # (5) each, and every family must have FAMILY_CONFIRM_WINS (4) there for the run to stop
    for name, value in [("FAMILY_EVERY", 3), ("VAL_WINS", 2), ("FAMILY_EPISODES", 2), ("FAMILY_WINS", 2),
                        ("FAMILY_CONFIRM", 5), ("FAMILY_CONFIRM_WINS", 4)]:
        monkeypatch.setattr(tacrl, name, value)
    rule = tacrl.StopRule(tacrl.Config(stop_held=3, train_episodes=10, randomize="reach,calib"))
    at, looked, confirmed = [], [], []

    def families(n):
        asked = looked if n == 2 else confirmed
        asked.append(ep + 1)
        return (first if n == 2 else confirm)[len(asked) - 1]
    for ep in range(10):
        if rule.learned(True, lambda: at.append(ep + 1) or train[len(at) - 1], families, lambda *_: None, ep):
            break
    assert at == [3, 6, 9][:len(at)] and ep + 1 == (stops or 10)
    assert looked == [a for a, w in zip(at, train) if w >= 2]             # the families where training's scene passed
    assert confirmed == [a for a, f in zip(looked, first) if min(f.values()) >= 2]     # ... and each family's look
    assert [h["episode"] for h in rule.history] == at and rule.stopped == bool(stops)
    assert [tacrl.StopRule.holds(h, ("reach", "calib")) for h in rule.history][-1] == bool(stops)
    restored = tacrl.StopRule(tacrl.Config(randomize="reach,calib"))
    restored.load_state_dict(rule.state_dict())
    assert restored.history == rule.history


def test_a_run_an_earlier_rule_stopped_trains_on_where_this_rule_does_not_confirm_it():
    first_look = {"episode": 360, "train": 20, "reach": 10, "calib": 9}          # no confirmation: 10 a family alone
    for randomize, stays in (("reach,calib", False), ("", True)):
        rule = tacrl.StopRule(tacrl.Config(randomize=randomize))
        rule.load_state_dict({"held": 60, "stopped": True, "history": [first_look]})
        assert rule.stopped == stays and rule.history == [first_look]
    rule = tacrl.StopRule(tacrl.Config(randomize="reach,calib"))
    for calib, stays in ((27, True), (26, False)):                        # confirmed, or not: 27 of 30 a family
        rule.load_state_dict({"held": 60, "stopped": True,
                              "history": [{**first_look, "confirm": {"reach": 30, "calib": calib}}]})
        assert rule.stopped == stays


def test_a_robust_run_validates_in_each_family_and_keeps_what_it_found(tmp_path, monkeypatch):
    # --robust with no curriculum, so that it is validated after episode 2; 0 wins pass everywhere, and eval.json
    # holds the validation: training's scene and each family's training side, one episode each, then two
    monkeypatch.setattr(sim, "MAX_STEPS", 4)
    for name, value in [("VAL_EPISODES", 1), ("FAMILY_EPISODES", 1), ("FAMILY_EVERY", 2), ("VAL_WINS", 0),
                        ("FAMILY_WINS", 0), ("FAMILY_CONFIRM", 2), ("FAMILY_CONFIRM_WINS", 0)]:
        monkeypatch.setattr(tacrl, name, value)
    cfg = tacrl.parse_args(TINY + ["--robust", "--randomize", "reach,calib", "--curriculum", "none", "--stop-held",
                                   "2", "--run-dir", str(tmp_path / "run")])
    assert (cfg.image_norm, cfg.tilt_deg, cfg.randomize) == ("image", 1.0, "reach,calib")   # a flag given wins
    result = tacrl.train(cfg, log=lambda *_: None)
    (seen,) = result["validation"]
    assert result["train_episodes"] == 2 and seen["episode"] == 2 and (seen["train"], seen["reach"]) == (0, 0)
    assert set(seen["confirm"]) == {"reach", "calib"} and all(0 <= n <= 2 for n in seen["confirm"].values())


def test_robust_is_one_flag_for_the_option_and_names_its_run():
    cfg = tacrl.parse_args(["--robust", "--seed", "2"])
    assert cfg.families == tuple(f for f in contexts.FAMILIES if f != "place") and cfg.image_norm == "image"
    assert (cfg.tilt_deg, cfg.train_episodes, cfg.stop_held) == (1.0, 600, 30)
    assert os.path.basename(cfg.run_dir) == "peg-robust-ts-ptv-adaptive-s2"
    other = tacrl.parse_args(["--robust", "--tilt-deg", "0", "--randomize", "touch"])
    assert os.path.basename(other.run_dir) == "peg-robust-ts-ptv-adaptive-rand-touch-tilt0-s0"
    assert tacrl.parse_args([]).randomize == ""
