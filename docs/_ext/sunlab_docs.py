"""Sphinx helpers for sunlab's site: the API pages from ``__all__``, the changelog from git,
a numpydoc parse check that is a build warning, and a check that executed notebooks show figures.

The API reference is generated, not written: every room of sunlab (a module or sub-package
directly under ``sunlab/``) gets a page listing its ``__all__`` with an autosummary table, one page
per name, and, for a sub-package, each public submodule with the names it exports that the
package does not re-export. A room that no group of :data:`GROUPS` names, or a group's room the
package no longer has, is a build warning, so the reference follows the package's rooms.
"""

from __future__ import annotations

import importlib
import itertools
import pkgutil
import re
import subprocess
import warnings
from pathlib import Path

from docutils import nodes
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

logger = logging.getLogger(__name__)

#: the API reference's sections, in the order of the package's layers (docs/architecture.md)
GROUPS: dict[str, tuple[str, ...]] = {
    "Schema and I/O": ("schema", "io", "integrity", "atomic"),
    "Plans and simulation": ("plans", "sim"),
    "Centroids": ("centroid", "screening"),
    "Geometry": ("geometry",),
    "Calibration": ("calibration",),
    "Statistics and the evaluation report": ("stats", "report"),
    "Multi-hole mask": ("multihole",),
    "Hardware": ("hardware",),
    "Reproduction": ("reproduce",),
    "Export": ("export",),
    "Figures and widgets": ("plots", "widgets"),
    "Foundations": ("errors", "options", "extras", "parallel"),
    "Command line, course and example data": ("cli", "course", "data.make_example"),
}

API_DIR = "api"


def rooms_on_disk(package_dir: Path) -> list[str]:
    """The rooms of sunlab: public modules and sub-packages directly under ``sunlab/``.

    Parameters
    ----------
    package_dir : pathlib.Path
        The ``sunlab`` package folder.

    Returns
    -------
    list of str
        Room names, sorted (``"io"``, ``"stats"``, ...); ``data`` counts by its modules
        (``"data.make_example"``), as it is a folder of files rather than a package.
    """
    found = [i.name for i in pkgutil.iter_modules([str(package_dir)]) if i.name[0] != "_"]
    return sorted(found + [f"data.{p.stem}" for p in (package_dir / "data").glob("[!_]*.py")])


def _exported(module) -> list[str]:
    """``module.__all__`` without the submodules it lists (they get their own section)."""
    # a submodule listed by name has its own section
    return [n for n in getattr(module, "__all__", ()) if not n.startswith("__")
            and getattr(getattr(module, n), "__name__", None) != f"{module.__name__}.{n}"]


def _autosummary(names: list[str]) -> list[str]:
    head = [".. autosummary::", "   :toctree: generated", "   :nosignatures:", ""]
    return head + [f"   {n}" for n in names] + [""] if names else []


def room_page(room: str) -> str:
    """The reST source of one room's API page.

    Parameters
    ----------
    room : str
        A room name as :func:`rooms_on_disk` gives it.

    Returns
    -------
    str
        The page: the module docstring, an autosummary of its ``__all__``, and for a
        sub-package each public submodule with the names only it exports.
    """
    name = f"sunlab.{room}"
    module = importlib.import_module(name)
    title = f"``{name}``"
    lines = [title, "=" * len(title), "", f".. automodule:: {name}", "   :no-members:", ""]
    lines += [f".. currentmodule:: {name}", ""] + _autosummary(_exported(module))
    if hasattr(module, "__path__"):
        # the names the package documents above (its stub's submodules are not among them)
        shown = set(_exported(module))
        for info in pkgutil.iter_modules(module.__path__):
            if info.name.startswith("_") or info.name == "__main__":
                continue
            sub_name = f"{name}.{info.name}"
            sub = importlib.import_module(sub_name)
            own = [n for n in _exported(sub) if n not in shown]
            head = f"``{sub_name}``"
            lines += [head, "-" * len(head), "", f".. automodule:: {sub_name}",
                      "   :no-members:"]
            if info.name in shown:
                # a function of the package shadows its module's name (sunlab.centroid.crlb)
                lines.append("   :no-index:")
            lines += ["", f".. currentmodule:: {sub_name}", ""]
            if own:
                lines += ["Names this module exports that the package does not re-export:", ""]
                lines += _autosummary(own)
            else:
                lines += [f"Every name it exports is documented under ``{name}`` above.", ""]
    return "\n".join(lines) + "\n"


def index_page(present) -> str:
    """The reST source of the API reference's index: the groups and their rooms (those of
    ``present``)."""
    title = "API reference"
    lines = [title, "=" * len(title), "",
             "Generated from the docstrings: every name in each room's ``__all__``, grouped as",
             "the package is (:doc:`../architecture`). Top-level names (``sunlab.SunlabError``,",
             "``sunlab.set_options``, ...) are documented in their rooms, :mod:`sunlab.errors`",
             "and :mod:`sunlab.options`.", "",
             ".. automodule:: sunlab", "   :no-members:", ""]
    for group, rooms in GROUPS.items():
        lines += [group, "-" * len(group), "", ".. toctree::", "   :maxdepth: 1", ""]
        lines += [f"   sunlab.{room}" for room in rooms if room in present] + [""]
    return "\n".join(lines) + "\n"


def generate_api(app, config) -> None:
    """Write ``docs/api/*.rst`` before Sphinx looks for its sources (``config-inited``)."""
    import sunlab

    on_disk = rooms_on_disk(Path(sunlab.__file__).parent)
    grouped = [room for rooms in GROUPS.values() for room in rooms]
    for room in sorted(set(on_disk) ^ set(grouped)):
        logger.warning("sunlab.%s is %s GROUPS in docs/_ext/sunlab_docs.py", room,
                       "in no group of the API reference: add it to" if room in on_disk
                       else "no room of the package: remove it from", type="sunlab",
                       subtype="api")
    grouped = [room for room in grouped if room in on_disk]
    out = Path(app.srcdir) / API_DIR
    out.mkdir(exist_ok=True)
    pages = {"index": index_page(grouped)} | {f"sunlab.{room}": room_page(room) for room in grouped}
    for page, text in pages.items():
        # an unchanged page keeps its mtime, so an incremental build does not reread it
        path = out / f"{page}.rst"
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
    # a name or room that left the surface leaves its page too: a stale page of an earlier
    # build would be a document outside every toctree
    keep = {f"{page}.rst" for page in pages} | {f"{n}.rst" for n in _entries(pages.values())}
    for stale in [*out.glob("*.rst"), *(out / "generated").glob("*.rst")]:
        if stale.name not in keep:
            stale.unlink()


def _entries(texts) -> set[str]:
    """The full names the autosummary tables of ``texts`` list (their generated pages)."""
    names, module = set(), ""
    for line in (ln for text in texts for ln in text.splitlines()):
        if line.startswith(".. currentmodule:: "):
            module = line.split(":: ", 1)[1].strip()
        elif line.startswith("   ") and not line.strip().startswith(":") and line.strip():
            names.add(f"{module}.{line.strip()}")
    return names


def numpydoc_problems(text: str) -> list[str]:
    """What numpydoc says when it parses one docstring.

    numpydoc reports a docstring it cannot parse with a Python warning (an unknown section) or
    an exception (a malformed section); Sphinx would print the first and count neither.

    Parameters
    ----------
    text : str
        The docstring, dedented.

    Returns
    -------
    list of str
        One message per problem; empty when the docstring parses.
    """
    from numpydoc.docscrape import NumpyDocString

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            NumpyDocString(text)
        except Exception as exc:  # numpydoc raises ValueError and others on malformed sections
            return [str(exc).splitlines()[0]]
    return [str(w.message).splitlines()[0] for w in caught]


def check_docstring(app, what, name, obj, options, lines) -> None:
    """``autodoc-process-docstring`` hook, run before numpydoc's: a parse problem is a warning."""
    for problem in numpydoc_problems("\n".join(lines)):
        logger.warning("numpydoc cannot parse the docstring of %s: %s", name, problem,
                       type="sunlab", subtype="numpydoc")


class ChangelogDirective(SphinxDirective):
    """``{sunlab-changelog}``: the git history, newest day first, one item per commit."""

    has_content = False

    def run(self):
        root = Path(self.env.srcdir).parent
        try:
            out = subprocess.run(
                ["git", "log", "--no-merges", "--date=short", "--format=%ad%x09%h%x09%s"],
                cwd=root, capture_output=True, text=True, check=True).stdout
        except (OSError, subprocess.CalledProcessError) as exc:
            logger.warning("the changelog needs the git history: build from a git clone (%s)",
                           exc, location=self.get_location(), type="sunlab",
                           subtype="changelog")
            return []
        result = []
        rows = (line.split("\t", 2) for line in out.splitlines())
        for day, commits in itertools.groupby(rows, key=lambda row: row[0]):
            items = [nodes.list_item("", nodes.paragraph("", "", nodes.literal(text=sha),
                                                         nodes.Text(" " + subject)))
                     for _, sha, subject in commits]
            result += [nodes.rubric(text=f"{day} ({len(items)} commits)"),
                       nodes.bullet_list("", *items)]
        return result


def locate(name: str):
    """The object a dotted sunlab name points to, with its parent.

    Parameters
    ----------
    name : str
        A dotted name starting with ``sunlab`` (``"sunlab.io.read.open_centroids"``).

    Returns
    -------
    tuple or None
        ``(obj, parent, attr)``: the object, the module or class it was read from and its name
        there; None when no such object exists.
    """
    parts = name.split(".")
    if parts[0] != "sunlab":
        return None
    for i in range(len(parts), 0, -1):  # the longest importable prefix, then attributes
        try:
            obj, parent, attr = importlib.import_module(".".join(parts[:i])), None, parts[i - 1]
            break
        except ImportError:
            continue
    for attr in parts[i:]:
        parent, obj = obj, getattr(obj, attr, _MISSING)
        if obj is _MISSING:
            return None
    return obj, parent, attr


_MISSING = object()


def _owner(cls: type, attr: str) -> type:
    """The class of ``cls``'s method resolution order that defines ``attr``."""
    return next((klass for klass in cls.__mro__ if attr in vars(klass)), cls)


def _key(found):
    """What identifies a documented object whatever path names it."""
    obj, parent, attr = found
    if isinstance(parent, type):
        return ("member", id(_owner(parent, attr)), attr)
    if isinstance(obj, type) or callable(obj) or hasattr(obj, "__path__") or parent is None:
        return ("object", id(obj))
    return ("data", attr, id(obj))


def _home_module(found) -> str | None:
    """The module whose source holds a documented object (a member: its defining class's)."""
    obj, parent, attr = found
    if isinstance(parent, type):
        return _owner(parent, attr).__module__
    if hasattr(obj, "__path__") or parent is None:
        return getattr(obj, "__name__", None)
    module = getattr(obj, "__module__", None)
    return module if isinstance(module, str) else getattr(parent, "__name__", None)


_DOCSTRING_OF = re.compile(r"docstring of (\S+)")


_DOCUMENTED: dict[int, dict] = {}


def _documented(env) -> dict:
    """Key of each object sunlab's pages document -> its documented name (built once)."""
    index = _DOCUMENTED.get(id(env))
    if index is None:
        index = {}
        for name, entry in sorted(env.domains["py"].objects.items()):
            if getattr(entry, "aliased", False) or not name.startswith("sunlab"):
                continue
            found = locate(name)
            if found is not None:
                index.setdefault(_key(found), name)
        _DOCUMENTED.clear()
        _DOCUMENTED[id(env)] = index
    return index


def resolve_by_object(app, env, node, contnode):
    """``missing-reference`` hook: a reference to a sunlab object under another of its names.

    A docstring names an object where it is defined (``sunlab.multihole.defects.robust_z``),
    relative to its own module (``load`` in ``sunlab.calibration.artifact``) or through a
    re-export (``sunlab.SunlabError``), while the reference documents it once, under the name
    its room exports. The target is looked up as Python would (the current class, the current
    module and its parent packages, then as written); if it is an object the site documents,
    the reference points to that page. A name that is no object stays a broken reference.
    """
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"]
    modname, clsname = node.get("py:module"), node.get("py:class")
    # the module whose source the docstring is in: names there are what its author meant
    m = _DOCSTRING_OF.search(node.source or "")
    home = locate(m.group(1)) if m else None
    scopes = [modname, home and _home_module(home)]
    candidates = [f"{modname}.{clsname}.{target}"] if modname and clsname else []
    for scope in filter(None, scopes):
        parts = scope.split(".")
        candidates += [".".join(parts[:i] + [target]) for i in range(len(parts), 0, -1)]
    candidates.append(target)
    index = _documented(env)
    domain = env.domains["py"]
    names, undocumented = [], None
    for candidate in candidates:
        found = locate(candidate)
        if found is None or not (_home_module(found) or "").startswith("sunlab"):
            continue  # no object, or another project's (``os.replace`` read via sunlab.atomic)
        name = index.get(_key(found))
        if name is None:
            undocumented = undocumented or candidate
        else:
            names.append(name)
    if not names and undocumented is None:
        # a partial name (``Calibration.predict_xy``): the one documented name ending with it
        names = [n for n in index.values() if n.endswith(f".{target}")]
        if len(names) > 1:
            return None
    for name in names[:1]:
        for reftype in (node["reftype"], "obj"):
            ref = domain.resolve_xref(env, node.get("refdoc", ""), app.builder, reftype, name,
                                      node, contnode)
            if ref is not None:
                return ref
    if undocumented is not None:
        # a real sunlab object without a page (private, or outside every __all__): shown as
        # code, not a link, and listed at the end of the build; a name that is no object
        # stays a broken reference
        _UNLINKED.add(undocumented)
        return contnode
    return None


_UNLINKED: set[str] = set()


def report_unlinked(app, exception) -> None:
    """``build-finished``: name the references shown without a link."""
    if _UNLINKED:
        logger.info("references to sunlab objects that have no page (shown as code): %s",
                    ", ".join(sorted(_UNLINKED)))


_IMG = re.compile(r"<img\b[^>]*\bsrc=\"[^\"]*_images/", re.I)


def check_notebook_figures(app, exception) -> None:
    """After an executing build, every notebook page must hold at least one figure image."""
    if exception is not None or app.builder.format != "html":
        return
    if app.config.nb_execution_mode == "off":
        return
    for doc in sorted(app.env.found_docs):
        if not doc.startswith("notebooks/"):
            continue
        html = Path(app.outdir, f"{doc}.html")
        if html.exists() and not _IMG.search(html.read_text(encoding="utf-8")):
            logger.warning("%s.html holds no figure image: did its cells run?", doc,
                           type="sunlab", subtype="figures")


def skip_foreign_member(app, what, name, obj, skip, options):
    """``autodoc-skip-member``: a class's members defined outside sunlab (a matplotlib base's
    ``set``) are documented by their own project, not here."""
    module = getattr(obj, "__module__", None)
    if what == "class" and isinstance(module, str) and not module.startswith("sunlab"):
        return True
    return None


def setup(app):
    import sunlab_widgets

    sunlab_widgets.install()
    app.connect("autodoc-skip-member", skip_foreign_member)
    app.connect("config-inited", generate_api)
    # before numpydoc's own handler (priority 500), so it sees the docstring as written
    app.connect("autodoc-process-docstring", check_docstring, priority=400)
    app.connect("build-finished", check_notebook_figures)
    app.connect("missing-reference", resolve_by_object)
    app.connect("build-finished", report_unlinked)
    app.add_directive("sunlab-changelog", ChangelogDirective)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
