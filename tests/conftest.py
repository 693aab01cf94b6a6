"""Every test starts in an empty working directory of its own, so that what a user has in runs/ or
results/ (the quickstart's run, finished or still training) never meets a test, and no test leaves
files where pytest was started. Tests that need the project's files name them from ROOT."""
import os

import pytest
import torch

if os.environ.get("PYTEST_XDIST_WORKER_COUNT"):     # pytest -n: threads x workers never more than the cores
    torch.set_num_threads(max(1, (os.cpu_count() or 1) // int(os.environ["PYTEST_XDIST_WORKER_COUNT"])))


@pytest.fixture(autouse=True)
def own_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
