"""Sphinx configuration of the sb3-saeir documentation (``make docs``)."""

import importlib.util
import os
import sys

sys.path.insert(0, os.path.abspath(".."))

with open(os.path.join(os.path.dirname(__file__), "..", "sb3_saeir", "version.txt")) as file_handler:
    release = file_handler.read().strip()

project = "sb3-saeir"
author = "sb3-saeir contributors"
copyright = "sb3-saeir contributors"  # noqa: A001 (Sphinx's name)
version = release

extensions = [
    "myst_parser",  # the pages are Markdown (MyST), as SB3's
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
    "sphinx.ext.mathjax",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "results/**/*.md", "results/**/failures.txt"]  # results/: what the benchmark wrote

# MyST: heading anchors for links such as tasks.md#the-reward-two-readings; $...$ maths.
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

# autodoc: SB3's settings (type hints in the description, members in source order).
autodoc_typehints = "description"
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_inherit_docstrings = False  # inherited gymnasium/SB3 docstrings are not ours (some are Google style)
# Optional extras imported at module level (optuna, sqlalchemy: the zoo extra): mocked only where they are missing,
# so `pip install -e ".[docs]"` alone builds the API reference too.
autodoc_mock_imports = [name for name in ("optuna", "sqlalchemy", "rl_zoo3", "gfootball", "ray") if importlib.util.find_spec(name) is None]
napoleon_google_docstring = False
napoleon_numpy_docstring = False

# Every cross-reference to the package must resolve (references to numpy, torch, SB3, ... cannot be checked offline:
# there is no intersphinx inventory without internet, so they are ignored).
nitpicky = True
nitpick_ignore_regex = [(r"py:.*", r"^(?!sb3_saeir\.).*"), (r"py:.*", r"sb3_saeir\..*\.Self[A-Z]\w*"), (r"py:.*", r"sb3_saeir\..*\.BonusClass")]  # TypeVars

# linkcheck: internal links only (the build machine has no internet).
linkcheck_ignore = [r"https?://.*"]

html_theme = "furo"
html_title = f"sb3-saeir {release}"
html_static_path: list[str] = []


def _resolve_reexport(app, env, node, contnode):
    """Resolve a reference to a re-exported name (``sb3_saeir.MultiAgentVecEnv``, ``sb3_saeir.mappo.MlpPolicy``) to the
    place where the object is documented (``sb3_saeir.common.vec_env.base.MultiAgentVecEnv``)."""
    import importlib

    target = node.get("reftarget", "")
    if node.get("refdomain") != "py" or not target.startswith("sb3_saeir."):
        return None
    parts = target.split(".")
    for split in range(len(parts) - 1, 0, -1):  # the longest importable module prefix, then attributes
        try:
            obj = importlib.import_module(".".join(parts[:split]))
        except ImportError:
            continue
        try:
            for name in parts[split:]:
                obj = getattr(obj, name)
        except AttributeError:
            return None
        break
    else:
        return None
    owner = obj if hasattr(obj, "__qualname__") else None
    if owner is None:
        return None
    canonical = f"{owner.__module__}.{owner.__qualname__}"
    if canonical == target:
        return None
    new_node = node.deepcopy()
    new_node["reftarget"] = canonical
    return env.get_domain("py").resolve_xref(env, node["refdoc"], app.builder, node["reftype"], canonical, new_node, contnode)


def setup(app):
    app.connect("missing-reference", _resolve_reexport)
