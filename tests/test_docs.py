"""The README's code map says how long each file is; a reader sizes the project by it, so it must be true."""
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def lines_of(path):
    """Lines of a file, or of a folder's .py files together."""
    paths = [os.path.join(path, f) for f in sorted(os.listdir(path)) if f.endswith(".py")] if os.path.isdir(path) \
        else [path]
    total = 0
    for p in paths:
        with open(p) as f:
            total += sum(1 for _ in f)
    return total


def test_the_readme_code_map_gives_each_file_its_line_count():
    with open(os.path.join(ROOT, "README.md")) as f:
        rows = re.findall(r"^\| `([\w./]+)` \| (\d+) \|", f.read(), re.M)
    assert len(rows) >= 9, "the code map's rows were not found"
    counted = {f: (int(n), lines_of(os.path.join(ROOT, f))) for f, n in rows}
    wrong = {f: said_now for f, said_now in counted.items() if said_now[0] != said_now[1]}
    assert not wrong, f"README says {{file: (lines said, lines now)}}: {wrong}"


def test_the_readme_holds_the_places_the_report_writes_its_numbers_in():
    """The report makes the README's result tables and its sentences of results anew in place (report.py --readme):
    each must be where it looks for it."""
    import sys
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import report
    path = os.path.join(ROOT, "README.md")
    for caption in (report.README_TABLE1, report.README_CONTEXTS, report.README_FAMILIES):
        assert len(report.readme_table(path, caption)) >= 3, caption        # a header, its rule, a row
    with open(path) as f:
        text = f.read()
    for name, (pattern, _) in report.README_SENTENCES.items():
        assert pattern.search(text), name
