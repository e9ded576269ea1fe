"""Sphinx configuration of the robofdi manual.

Builds offline (no intersphinx, no remote assets) and is meant to run with warnings as errors::

    sphinx-build -W --keep-going -b html docs docs/_build/html

The API reference is generated from the docstrings by autosummary (``reference/api.md``, ``:recursive:`` over
the ``robofdi`` package), so a module that is added, renamed or removed changes the reference by itself.
"""
from __future__ import annotations

import importlib.util
import re
import warnings
import os
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")
# robosuite imports glfw, which warns on a headless machine; the reference needs no window.
warnings.filterwarnings("ignore", message=r".*DISPLAY environment variable is missing")
ROOT = Path(__file__).resolve().parents[1]

project = "robofdi"
author = "the robofdi developers"
copyright = "robofdi developers, MIT licence"
try:
    from importlib.metadata import version as _version

    release = _version("robofdi")
except Exception:  # noqa: BLE001 - a docs build from a checkout that is not installed
    release = "0.1.0"
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
]

# Markdown pages (MyST) beside reStructuredText; headings get anchors, so [x](page.md#a-heading) links work.
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]
templates_path = ["_templates"]

# The API reference: one page per module, generated at build time.
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
# Methods that override a third-party base (dm_env.Environment.step, …) would inherit its docstring and its style.
autodoc_inherit_docstrings = False
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True
napoleon_google_docstring = False
napoleon_numpy_docstring = True

# Optional dependencies (the robosuite / dm_control adapters, Dask): mocked when they are not installed, so the
# reference builds with the ``docs`` extra alone; with the ``test`` extra installed they import for real.
_OPTIONAL = ["robosuite", "dm_control", "dm_env", "dask", "distributed", "pynput", "gymnasium", "mcap", "mcap_ros2", "rerun"]
autodoc_mock_imports = [m for m in _OPTIONAL if importlib.util.find_spec(m) is None]

# No network at build time: no intersphinx, no remote assets (the pages write their maths in Unicode).
html_theme = "furo"
html_title = f"robofdi {release}"
html_static_path: list[str] = []
html_show_sourcelink = False


# The docstrings write maths in Unicode, where |x| is an absolute value and a name such as coefs_ is an attribute;
# reStructuredText would read |x| as a substitution and coefs_ as a link. Escape both in the docstrings' prose
# (inline ``literals`` and ``::`` literal blocks are left as they are), so the source stays plain and readable.
_BARS = re.compile(r"\|([^|\s](?:[^|]*?[^|\s])?)\|")
_LINK_LIKE = re.compile(r"(?<![\w`])(\w*[^\W_])_(?=[\s,.;:)\]]|$)")
_INLINE_LITERAL = re.compile(r"(``.*?``)")


def _escape_prose(line: str) -> str:
    parts = _INLINE_LITERAL.split(line)
    return "".join(p if p.startswith("``") else _LINK_LIKE.sub(r"\1\\_", _BARS.sub(r"\\|\1\\|", p)) for p in parts)


def _escape_docstring(app, what, name, obj, options, lines):
    literal_indent = None
    for i, line in enumerate(lines):
        indent = len(line) - len(line.lstrip())
        if literal_indent is not None:
            if not line.strip() or indent > literal_indent:
                continue
            literal_indent = None
        lines[i] = _escape_prose(line)
        if line.rstrip().endswith("::"):
            literal_indent = indent


def setup(app):
    app.connect("autodoc-process-docstring", _escape_docstring)
