"""Sphinx configuration of sunlab's site (``make docs``; tests/test_docs.py builds it without
running the notebooks).

Environment:

``SUNLAB_DOCS_EXECUTE``
    ``force`` (``make docs``): run every notebook at build time, in quick mode
    (``SUNLAB_QUICK=1``); ``off`` (the test): render the notebooks as committed, without outputs.
``SUNLAB_DOCS_INVENTORIES``
    A folder of intersphinx inventories named ``numpy.inv``, ``scipy.inv``, ... (Sphinx's
    ``objects.inv`` of each project), or ``online`` to fetch them from the projects' sites. Unset,
    there is no intersphinx: the build machines have no internet, and no installed package ships
    its inventory. References to a project without an inventory then render as plain code,
    and only those are exempt from the nitpicky check; sunlab's own references must resolve.
"""

from __future__ import annotations

import builtins
import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))
# the sunlab of this checkout, whatever is installed
sys.path.insert(0, str(DOCS.parent))

import sunlab  # noqa: E402

project = "sunlab"
author = "sunlab developers"
copyright = "sunlab developers"
release = version = sunlab.__version__

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sunlab_docs",
]

root_doc = "index"
exclude_patterns = ["_build", "images/*.py", "**.ipynb_checkpoints", "jupyter_execute"]
templates_path = ["_templates"]
nitpicky = True
# a reference to an anchor of another page is checked too
myst_heading_anchors = 4
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
suppress_warnings = [
    # numpydoc turns a References entry into a citation; a docstring need not cite it inline
    "ref.citation",
]

# --- the notebooks ----------------------------------------------------------------------------
nb_execution_mode = os.environ.get("SUNLAB_DOCS_EXECUTE", "force")
nb_execution_timeout = 900  # the slowest quick-mode cell (06's Table 5) takes about a minute
nb_execution_raise_on_error = True  # a failing cell stops the build
nb_execution_show_tb = True
nb_execution_in_temp = False  # cells run in notebooks/, as a reader runs them
nb_merge_streams = True
# widgets are drawn from their saved state as static HTML (_ext/sunlab_widgets.py), so no page
# loads ipywidgets' JavaScript from a CDN
nb_ipywidgets_js = {}
if nb_execution_mode != "off":
    os.environ["SUNLAB_QUICK"] = "1"  # the small settings, as in `make test`
    # the kernel's own inline backend: with MPLBACKEND=Agg figures would show as text
    os.environ.pop("MPLBACKEND", None)

# --- the API reference ------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = True
autodoc_typehints = "none"  # numpydoc's Parameters carry the types and units
numpydoc_show_class_members = False  # the class template lists members with autodoc
numpydoc_xref_param_type = False
numpydoc_class_members_toctree = False

# --- references to other projects ----------------------------------------------------------------
_MODULES = (r"os|pathlib|collections|typing|dataclasses|enum|abc|argparse|subprocess|json|logging"
            r"|threading|concurrent|multiprocessing|signal|io|contextlib|time|socket")
#: project -> (its documentation, the names its references start with)
PROJECTS = {
    "python": ("https://docs.python.org/3/", r"(builtins\.)?(" + "|".join(
        n for n in dir(builtins) if not n.startswith("_")) + rf")|({_MODULES})\.\S+"),
    "numpy": ("https://numpy.org/doc/stable/", r"(numpy|np)(\.\S+)?"),
    "scipy": ("https://docs.scipy.org/doc/scipy/", r"scipy(\.\S+)?"),
    "xarray": ("https://docs.xarray.dev/en/stable/", r"(xarray|xr)(\.\S+)?"),
    "pandas": ("https://pandas.pydata.org/docs/", r"(pandas|pd)(\.\S+)?"),
    "matplotlib": ("https://matplotlib.org/stable/", r"(matplotlib|mpl|plt)(\.\S+)?"),
    "torch": ("https://docs.pytorch.org/docs/stable/", r"torch(\.\S+)?"),
    "dask": ("https://docs.dask.org/en/stable/", r"(dask|distributed)(\.\S+)?"),
    "pyserial": ("https://pyserial.readthedocs.io/en/latest/", r"serial(\.\S+)?"),
}
_inventories = os.environ.get("SUNLAB_DOCS_INVENTORIES", "")
intersphinx_mapping = {}
nitpick_ignore_regex = []
for name, (url, prefix) in PROJECTS.items():
    inv = Path(_inventories) / f"{name}.inv"
    if _inventories == "online" or (_inventories and inv.is_file()):
        intersphinx_mapping[name] = (url, None if _inventories == "online" else str(inv))
    else:
        nitpick_ignore_regex.append((r"py:.*", prefix))

html_theme = "pydata_sphinx_theme"
html_title = "sunlab"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_static_path = []
html_last_updated_fmt = None
