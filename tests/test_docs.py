"""The README and docs/ as a reader meets them: every block the report makes has its place in a page, each block is
closed, prose lines fit 120 columns (a figure's line in docs/ aside), and every link between the pages leads somewhere. (Their numbers are the
report's: `python tools/report.py --check` compares them with the archive; CI runs it.)"""
import glob
import os
import re

import pages
import results
import scenes

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAGES = [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
OTHER_BLOCKS = ("code-map", "critics-runs", "objects", "scenes")   # report.py's code map, compare.py's, objects.py's,
#                                                                     scenes.py's every scene


def read(path):
    with open(path) as f:
        return f.read()


def test_every_block_the_report_makes_has_a_page_and_each_block_is_closed():
    held = {}
    for p in PAGES:
        text = read(p)
        assert len(pages.blocks(text)) == text.count("<!-- report: ") == text.count("<!-- end -->"), p
        held.update(dict.fromkeys(pages.blocks(text), p))
    missing = {*results.BLOCKS, *scenes.BLOCKS, *OTHER_BLOCKS} - set(held)
    assert not missing, sorted(missing)


def test_prose_fits_120_columns_and_links_between_pages_lead_somewhere():
    for p in PAGES:
        if p.endswith("HISTORY.md"):                      # the account, kept as written
            continue
        fenced = False
        for line in read(p).split("\n"):
            fenced ^= line.startswith("```")
            figure = line.startswith("![") and not p.endswith("README.md")     # a file's long name in docs/
            assert fenced or figure or line.startswith("|") or len(line) <= 120, (p, line[:60])
        for target in re.findall(r"\]\(([^)#\s]+)", read(p)):
            if "://" in target or target.startswith(("results/", "../results/")):   # the archive: not read by tests
                continue
            assert os.path.exists(os.path.join(os.path.dirname(p), target)), (p, target)
