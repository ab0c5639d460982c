"""Sphinx configuration of the OneOcean documentation.

Build (from the repository root; about the time given in the README's *Documentation*)::

    python3 -m sphinx -W -b html docs docs/_build/html

Tool choice: Sphinx with MyST-NB, numpydoc and furo, because the package's API is documented
in numpydoc docstrings (autodoc renders them as they are), tutorials are Markdown notebooks
that MyST-NB executes during the build, and ``-W`` turns every broken reference into an error.

Tutorials (``docs/tutorials/*.md``, MyST-NB text notebooks) are executed at every build
(``nb_execution_mode = "force"``: no cache), each in a fresh ``python3`` kernel whose working
directory is the notebook's own folder (``docs/tutorials/``, or its copy when the tests build a
copy of ``docs/``). The repository root is in the environment variable ``ONEOCEAN_REPO`` (set
here; the kernel inherits it), so a tutorial reaches the repository's files as
``Path(os.environ["ONEOCEAN_REPO"]) / "config" / "config.yaml"``; it should write its outputs
under a temporary folder (``tempfile.mkdtemp()``), not into the source tree. A cell that raises
fails the build (``nb_execution_raise_on_error``); each notebook may run for up to
``nb_execution_timeout`` seconds per cell. For drafting only, ``ONEOCEAN_DOCS_NO_EXECUTE=1``
builds without executing them (their outputs are then missing).

``docs/reference/`` is written at each build by ``docs/_ext/oneocean_reference.py`` (config
keys, CLI, tasks, API); it is git-ignored: edit the sources it is made from.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
REPO = Path(os.environ.get("ONEOCEAN_REPO", DOCS.parent)).resolve()
os.environ["ONEOCEAN_REPO"] = str(REPO)
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(REPO / "src"))
# keep the kernels and the build on one thread each: the build shares small machines
os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

import oneocean  # noqa: E402

project = "OneOcean"
author = "The OneOcean authors"
copyright = "2026, the OneOcean authors (MIT licence)"
version = release = getattr(oneocean, "__version__", "0.1.0")

extensions = [
    "myst_nb",                      # Markdown pages and executed Markdown notebooks
    "sphinx.ext.autodoc",
    "numpydoc",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "oneocean_reference",           # docs/_ext: config, CLI, tasks and API pages at build time
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb"}
root_doc = "index"
exclude_patterns = ["_build", "**/.ipynb_checkpoints", "Thumbs.db", ".DS_Store",
                    "_static/screenshots"]
templates_path: list[str] = []

# ---- MyST: headings get anchors (#section-title links resolve and are checked), local links
# to files that are not documents are warnings (hence errors under -W)
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath", "attrs_inline"]
myst_heading_anchors = 3

suppress_warnings: list[str] = []

# ---- MyST-NB: execute every tutorial at every build
nb_execution_mode = "force"
if os.environ.get("ONEOCEAN_DOCS_NO_EXECUTE"):   # drafting only: tutorials shown unexecuted
    nb_execution_mode = "off"
    suppress_warnings.append("myst-nb.lexer")   # unexecuted notebooks name no language
nb_execution_timeout = 900
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_execution_in_temp = False
nb_merge_streams = True
nb_kernel_rgx_aliases = {".*": "python3"}

# ---- autodoc + numpydoc: the API reference from the docstrings
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"          # the numpydoc sections carry types and units
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_attributes_as_param_list = True

# ---- HTML
html_theme = "furo"
html_title = "OneOcean"
html_static_path = ["_static"]
html_css_files = ["custom.css"]
html_last_updated_fmt = None
html_show_sourcelink = False
html_theme_options = {"navigation_with_keys": True}

# no network during the build: nothing here fetches external inventories or URLs
intersphinx_mapping: dict = {}
linkcheck_ignore = [r"https?://.*"]
