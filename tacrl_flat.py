"""tacrl_flat.py: tacrl's modules are flat, top-level names (sim, control, policy, evaluate, ...), and another
installed package may take one of them: python-control's `control`, Hugging Face's `evaluate`, OpenAI's
`baselines`. Then `import sim` would read the other package's `control` and fail deep inside with an error that
names neither. Each of our modules that imports another of ours imports this file first: it finds every one of
them beside this file, or stops the import with one line naming the clash.
"""
import importlib.util
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
MODULES = ("baselines", "cli", "command", "contexts", "control", "curriculum", "evaluate", "policy", "rundir",
           "scene", "shapes", "sim", "tacrl")


def origin(name):
    """The file `import name` reads now (None where no module has that name)."""
    module = sys.modules.get(name)
    if module is not None:
        return getattr(module, "__file__", None)
    spec = importlib.util.find_spec(name)
    return spec.origin if spec is not None else None


def clashes():
    """[(name, the file it imports instead of ours)] for each of MODULES that another package's file shadows (a
    module missing altogether, as where a few files were copied into another project, is no clash)."""
    found = [(name, origin(name)) for name in MODULES]
    return [(name, path) for name, path in found
            if path is not None and os.path.dirname(os.path.abspath(path)) != HERE]


_clashes = clashes()
if _clashes:
    name, path = _clashes[0]
    raise ImportError(f"tacrl: `import {name}` reads {path}, another package's module, not tacrl's {name}.py in "
                      f"{HERE}: run tacrl from its folder, or uninstall the package that takes the name {name!r}")
