"""Every test starts in an empty working directory of its own, so that what a user has in runs/ or
results/ (the quickstart's run, finished or still training) never meets a test, and no test leaves
files where pytest was started. Tests that need the project's files name them from ROOT."""
import pytest


@pytest.fixture(autouse=True)
def own_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
