"""Sphinx configuration of varint's documentation.

Build (from the repository root; README.md gives the same command)::

    pip install ".[docs]" && python -m sphinx -W --keep-going -b html docs docs/_build/html

The gallery (docs/examples/plot_*.py) is executed at every build; with
VARINT_DOCS_QUICK=1 the examples run shorter integrations and coarser maps
(CI does this). docs/contributing.rst says how to add a page or an example.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
# The checkout's own varint, as the tests import it, and the local extension.
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE / "_ext"))

import varint  # noqa: E402

project = "varint"
author = "the varint developers"
copyright = "the varint developers"
version = release = varint.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "myst_parser",
    "varint_docs",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_mathjax", "README.md", "**/GALLERY_HEADER.rst", "auto_examples/*.ipynb",
                    "auto_examples/*.py", "auto_examples/*.zip"]
templates_path = ["_templates"]
default_role = "code"
pygments_style = "sphinx"

# -- API reference ----------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
autodoc_typehints = "none"          # numpydoc's Parameters give the types
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "member-order": "bysource"}
numpydoc_show_class_members = False  # autosummary lists them
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks = set()

# -- Markdown (the report, the changelog) -----------------------------------
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3

# -- Gallery ----------------------------------------------------------------
QUICK = bool(os.environ.get("VARINT_DOCS_QUICK"))

sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "within_subsection_order": "FileNameSortKey",
    "doc_module": ("varint",),
    "backreferences_dir": "api/generated/backreferences",
    "reference_url": {"varint": None},
    "download_all_examples": False,
    "remove_config_comments": True,
    "min_reported_time": 1,
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "show_memory": False,
    # Only what an example prints or draws, not the repr of a cell's last
    # expression (e.g. the Text object of set_title).
    "capture_repr": (),
}

# -- Math, offline ------------------------------------------------------------
# MathJax ships with the site (no CDN: pages must read right on a machine
# without internet). The build installs the npm package once into
# docs/_mathjax (ignored by git) and copies its browser bundle into _static.
MATHJAX_VERSION = "3.2.2"
MATHJAX = HERE / "_mathjax"


def _local_mathjax():
    """The folder whose ``mathjax/tex-chtml.js`` the pages load."""
    bundle = MATHJAX / "node_modules" / "mathjax" / "es5"
    static = MATHJAX / f"static-{MATHJAX_VERSION}"
    if (static / "mathjax" / "tex-chtml.js").is_file():
        return static
    if not (bundle / "tex-chtml.js").is_file():
        npm = shutil.which("npm")
        if npm is None:
            raise RuntimeError(
                "the documentation ships MathJax for offline reading and installs it with npm, "
                "which is not on PATH: install Node.js (e.g. apt-get install npm), or run "
                f"'npm install --prefix docs/_mathjax mathjax@{MATHJAX_VERSION}' elsewhere and "
                "copy docs/_mathjax here")
        subprocess.run([npm, "install", "--no-audit", "--no-fund", "--silent", "--prefix",
                        str(MATHJAX), f"mathjax@{MATHJAX_VERSION}"], check=True)
    shutil.copytree(bundle, static / "mathjax", dirs_exist_ok=True)
    return static


mathjax_path = "mathjax/tex-chtml.js"

# -- HTML -------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"varint {version}"
html_static_path = ["_static", str(_local_mathjax())]
html_css_files = ["varint.css"]
html_show_sourcelink = False
html_theme_options = {
    "logo": {"text": "varint"},
    "navbar_align": "left",
    "show_toc_level": 2,
    "navigation_with_keys": False,
    "header_links_before_dropdown": 6,
    # The report's wide tables take the whole width; its sections are in
    # the left navigation column.
    "secondary_sidebar_items": {"**": ["page-toc"], "report": []},
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version", "theme-version"],
}
# Pages without sub-pages: no empty navigation column, wider tables.
html_sidebars = {page: [] for page in ("index", "getting_started", "citing",
                                       "changelog", "contributing")}
html_sidebars["report"] = ["page-toc"]
