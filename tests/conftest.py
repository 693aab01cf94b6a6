"""Every test starts in an empty working directory of its own, so that what a user has in runs/ or
results/ (the quickstart's run, finished or still training) never meets a test, and no test leaves
files where pytest was started. Tests that need the project's files name them from ROOT."""
import os

import pytest

if os.environ.get("PYTEST_XDIST_WORKER_COUNT"):     # pytest -n: threads x workers never more than the cores
    import torch                                    # (in a worker only: the controller, which starts them, runs no test)
    torch.set_num_threads(max(1, (os.cpu_count() or 1) // int(os.environ["PYTEST_XDIST_WORKER_COUNT"])))

# `--dist loadfile` hands a worker a whole file at a time, in this order (`--no-loadscope-reorder`): the files
# whose tests take longest in all (`pytest --durations=0`) first, so that no worker is left alone with one at the
# end while the other has finished
LONGEST_FIRST = ("test_train.py", "test_sim.py", "test_faults.py", "test_cli.py", "test_families.py", "test_baselines.py",
                 "test_sweep.py", "test_errors.py")


def pytest_collection_modifyitems(items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))     # stable: each file's own order is kept


@pytest.fixture(autouse=True)
def own_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
