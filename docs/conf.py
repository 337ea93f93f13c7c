"""Sphinx configuration of krl's documentation site.

Build it (from the repository root; the ``docs`` extra pins Sphinx, MyST and the theme)::

    pip install -e ".[docs]" && sphinx-build -W --keep-going -b html docs docs/_build/html

The Markdown pages of ``docs/`` are the site's pages as they are (MyST); the API reference
(``docs/api/``) is generated from krl's docstrings by autodoc and napoleon (Google style). ``.ci/run``
builds it with ``-W``, so a broken link, reference or docstring fails CI.
"""

import importlib
import os
import pkgutil
import re
from pathlib import Path

from docutils import nodes
from docutils.statemachine import StringList
from sphinx import addnodes
from sphinx.ext.napoleon.docstring import GoogleDocstring
from sphinx.transforms.post_transforms import SphinxPostTransform
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

# Importing krl's modules must not need a display or an OpenGL library: nothing here renders.
os.environ.setdefault("MUJOCO_GL", "disable")

import krl  # after MUJOCO_GL is set

project = "krl"
author = "krl's authors"
copyright = "krl's authors (MIT licence)"
release = version = krl.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
# Pages are .md and .rst files; the build output and the figures' folders hold none.
exclude_patterns = ["_build", "figures/**"]

# The result pages krl report writes (docs/results/*/evaluation.md) go from "#" to "###"; GitHub renders
# that as written, and the generator (krl.eval.report), not the page, is where it would change.
suppress_warnings = ["myst.header"]

# MyST: GitHub's heading anchors, so that the pages' links (``page.md#a-heading``) work on GitHub and here.
myst_heading_anchors = 4
myst_enable_extensions = ["colon_fence"]

# autodoc + napoleon: the docstrings are Google style (Args:, Returns:, Raises:).
napoleon_google_docstring = True
napoleon_numpy_docstring = False
# Every object is documented once, in the module that defines it, not again where a package re-exports it.
autodoc_default_options = {"members": True, "member-order": "bysource", "ignore-module-all": True}
autodoc_typehints = "description"
autodoc_class_signature = "separated"

# krl's attribute docstrings are prose; their types come from the annotations. Napoleon would read the
# text before a first-line colon ("Distance ... U(low, high) [m]: the thesis's ...") as the type.
def _attribute_docstring_as_prose(self: GoogleDocstring) -> list[str]:
    return GoogleDocstring(self._dedent(self._consume_to_end()), self._config).lines()


GoogleDocstring._parse_attribute_docstring = _attribute_docstring_as_prose  # type: ignore[method-assign]


_LITERAL = re.compile(r"(``.+?``)")


def _bars_as_text(app, what, name, obj, options, lines):
    """krl's docstrings write absolute values and norms as ``|x|``, never reStructuredText's substitutions
    or grid tables: every ``|`` outside a literal is text."""
    for i, line in enumerate(lines):
        parts = _LITERAL.split(line)
        lines[i] = "".join(p if k % 2 else p.replace("|", "\\|") for k, p in enumerate(parts))


def _skip_namedtuple_aliases(app, what, name, obj, skip, options):
    """A NamedTuple's fields are described in its docstring's Attributes: section; their generated
    "Alias for field number N" docstrings would describe them a second time."""
    doc = getattr(obj, "__doc__", None) or ""
    return True if what == "class" and doc.startswith("Alias for field number") else None


html_theme = "furo"
html_title = f"krl {release}"
html_static_path: list[str] = []
html_show_sourcelink = False


class KrlModules(SphinxDirective):
    """``.. krl-modules:: krl.sim``: the package and every module under it, each under its own heading
    as autodoc's ``automodule``, found by walking the package (so a new module is documented without
    editing the page)."""

    required_arguments = 1

    def run(self):
        package = importlib.import_module(self.arguments[0])
        modules = pkgutil.walk_packages(package.__path__, package.__name__ + ".")
        names = [package.__name__, *sorted(m.name for m in modules if not m.name.endswith(".__main__"))]
        lines = []
        for name in names:
            lines += [f"``{name}``", "-" * (len(name) + 4), "", f".. automodule:: {name}", ""]
        node = nodes.section()
        node.document = self.state.document
        nested_parse_with_titles(self.state, StringList(lines, source=self.get_source_info()[0]), node)
        return node.children


class RepositoryPaths(SphinxPostTransform):
    """A link to a file of the repository outside docs/ (``../benchmarks/README.md``; README.md's
    ``evaluations/README.md``) or to a folder (``results/agent/``) works on GitHub but is no page of this
    site: it is shown as the path it names. A link to a path that does not exist is left to MyST, which
    reports it, so a broken link still fails the strict build."""

    default_priority = 8  # before MyST's resolver (9)

    def run(self, **kwargs):
        srcdir = Path(self.env.srcdir).resolve()
        root = srcdir.parent
        for node in list(self.document.findall(addnodes.pending_xref)):
            if node.get("reftype") != "myst":
                continue
            if node.get("refdomain") == "doc":
                target = (srcdir / (node["reftarget"] + ".md")).resolve()
            elif node.get("refdomain") is None and node.source:
                target = (Path(node.source).parent / node["reftarget"].split("#")[0]).resolve()
            else:
                continue
            outside = target.is_file() and not target.is_relative_to(srcdir)
            if not (outside or target.is_dir()) or not target.is_relative_to(root):
                continue
            path = target.relative_to(root).as_posix() + ("/" if target.is_dir() else "")
            shown = nodes.inline("", "", *node.children)
            if node.astext().strip("/") != path.strip("/"):
                shown += [nodes.Text(" ("), nodes.literal(path, path), nodes.Text(")")]
            node.replace_self(shown)


def setup(app):
    app.add_directive("krl-modules", KrlModules)
    app.add_post_transform(RepositoryPaths)
    app.connect("autodoc-skip-member", _skip_namedtuple_aliases)
    app.connect("autodoc-process-docstring", _bars_as_text)
