"""pages.py: the generated parts of hand-written pages. A page (README.md, a page of docs/) is prose a person writes,
with blocks the report makes from the archived runs between two markers, each block named:

    <!-- report: table1 -->
    | method | ... |
    <!-- end -->

fill() makes a page's named blocks anew in place and leaves every other line as it was; stale() says which of a
page's blocks differ from what the report makes now (typed by hand, or results/ changed since). No number of
results is typed: each stands in a block, made from the runs.
"""
import os
import re
import textwrap

BLOCK = re.compile(r"(<!-- report: ([\w-]+) -->\n)(.*?)(<!-- end -->)", re.S)


def blocks(text):
    """{name: content} of a page's blocks (content without its markers, ending in a newline or empty)."""
    return {m.group(2): m.group(3) for m in BLOCK.finditer(text)}


def wrap(text, width=120):
    """A block's markdown with its prose lines wrapped at `width` (a list item's go on indented); tables, headings,
    figures and fenced code as they are."""
    out, fenced = [], False
    for line in text.split("\n"):
        fenced ^= line.startswith("```")
        if fenced or line.startswith(("|", "#", "!", "```")) or len(line) <= width:
            out.append(line)
            continue
        item = re.match(r"(\s*(?:- |\d+\. ))", line)
        out += textwrap.wrap(line, width, subsequent_indent=" " * len(item.group(1)) if item else "",
                             break_long_words=False, break_on_hyphens=False)
    return "\n".join(out)


def fill(path, made, log=print):
    """Make the blocks of the page at `path` anew from `made` ({name: markdown text}); blocks whose names `made` has
    not got stay as they are. Returns the names filled."""
    with open(path) as f:
        text = f.read()
    filled = []

    def new(m):
        if m.group(2) not in made:
            return m.group(0)
        filled.append(m.group(2))
        return m.group(1) + wrap(made[m.group(2)].rstrip("\n")) + "\n" + m.group(4)
    text = BLOCK.sub(new, text)
    if filled:
        with open(path, "w") as f:
            f.write(text)
        log(f"wrote {path}'s {', '.join(filled)}")
    return filled


def stale(path, made):
    """The names of the page's blocks that `made` has and whose content differs from it."""
    with open(path) as f:
        have = blocks(f.read())
    return [name for name, text in have.items() if name in made and text.rstrip("\n") != wrap(made[name].rstrip("\n"))]


def fill_all(paths, made, log=print):
    """fill() each page that exists; returns the names of the blocks filled (a name of `made` missing from it is in
    no page)."""
    return {name for p in paths if os.path.exists(p) for name in fill(p, made, log)}
