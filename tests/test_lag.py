"""--lag 1: the next episode collected in a second process while the updates run. Killed in the middle of an
update phase and resumed, a run is the same run as one never stopped: the episode in flight is collected anew
with the weights and random states it started with."""
import csv
import json
import os

import numpy as np
import pytest

import policy
import tacrl

LAG = ["--task", "peg", "--error-mm", "1", "--train-episodes", "4", "--warmup", "1", "--updates", "2", "--batch", "8",
       "--buffer", "240", "--episodes", "1", "--eval-levels", "1", "--threads", "1", "--lag", "1"]
TIMES = ("env_s", "update_s", "elapsed_s")


def rows(run_dir):
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        return [{k: v for k, v in r.items() if k not in TIMES} for r in csv.DictReader(f)]


def test_a_lagged_run_killed_and_resumed_is_the_same_run_as_one_never_stopped(tmp_path, monkeypatch):
    whole, cut = str(tmp_path / "whole"), str(tmp_path / "cut")
    tacrl.train(tacrl.parse_args(LAG + ["--run-dir", whole]), log=lambda *_: None)
    calls, real_update = [], policy.SAC.update

    def killed_in_episode_3(sac, batch):        # episode 2's updates are calls 1-2, episode 3's 3-4
        calls.append(np.any(batch[1]))         # (not the start-up probe's, whose actions are all zero)
        if sum(calls) == 3:
            raise KeyboardInterrupt
        return real_update(sac, batch)
    monkeypatch.setattr(policy.SAC, "update", killed_in_episode_3)
    with pytest.raises(KeyboardInterrupt, match="--resume"):
        tacrl.train(tacrl.parse_args(LAG + ["--run-dir", cut]), log=lambda *_: None)
    assert len(rows(cut)) == 2                  # episodes 3 (in its updates) and 4 (in flight) are lost
    monkeypatch.setattr(policy.SAC, "update", real_update)
    tacrl.train(tacrl.parse_args(["--resume", cut]), log=lambda *_: None)
    assert rows(cut) == rows(whole) and len(rows(whole)) == 4
    evals = [json.load(open(os.path.join(d, "eval.json")))["rows"] for d in (whole, cut)]
    assert evals[0] == evals[1]
