"""MkDocs hooks of the documentation site (``hooks:`` in mkdocs.yml): the site works offline.

* MathJax 3 is served by the site itself, from the copy that the PyPI package
  ``django-static-mathjax`` ships (MathJax 3.2.2, Apache 2.0; a plain wheel of static files, it
  needs no Django): :func:`on_files` adds its CommonHTML build (``es5/tex-mml-chtml.js``, the TeX
  extensions it loads on demand, its fonts, menu and accessibility parts, the licence) under
  ``javascripts/mathjax/``. No CDN is contacted; ``mkdocs serve`` serves the same files.
* mkdocs-jupyter's notebook pages carry two loaders that point elsewhere: an empty
  ``<script src="">`` where a MathJax 2 URL would go (the site's MathJax 3 typesets the
  notebooks) and a module script that imports mermaid from a CDN when a notebook has mermaid
  diagrams (ours have none). :func:`on_post_page` removes both.

Written by hand: neither MkDocs nor mkdocs-material copies a MathJax from a Python package, and
mkdocs-material's privacy plugin, which downloads external assets, needs the network at build time.
"""

from __future__ import annotations

import importlib.util
import os
import re

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File

#: Where the site holds MathJax (mkdocs.yml's extra_javascript names ``MATHJAX_DIR/es5/tex-mml-chtml.js``).
MATHJAX_DIR = "javascripts/mathjax"
#: The single-file MathJax builds other than the one the site loads (each 1-2 MB, not needed).
_OTHER_BUILD = re.compile(r"^es5/(?!tex-mml-chtml\.js$)[^/]+\.js$")


def mathjax_root() -> str:
    """The folder of the MathJax distribution installed by ``django-static-mathjax``."""
    spec = importlib.util.find_spec("mathjax")
    root = os.path.join(list(spec.submodule_search_locations)[0], "static", "mathjax") if spec else ""
    if not os.path.isfile(os.path.join(root, "es5", "tex-mml-chtml.js")):
        raise PluginError("MathJax not found: install the documentation's requirements, "
                          "python3 -m pip install -e \".[docs]\" (django-static-mathjax)")
    return root


def _wanted(rel: str) -> bool:
    return rel == "LICENSE" or (rel.startswith("es5/") and not _OTHER_BUILD.match(rel)
                                and not rel.startswith("es5/output/svg"))


def on_files(files, config):
    root = mathjax_root()
    for folder, _, names in os.walk(root):
        for name in names:
            path = os.path.join(folder, name)
            rel = os.path.relpath(path, root).replace(os.sep, "/")
            if _wanted(rel):
                files.append(File.generated(config, f"{MATHJAX_DIR}/{rel}", abs_src_path=path))
    return files


_EMPTY_SCRIPT = re.compile(r'<script src="">\s*</script>')
_MERMAID_LOADER = re.compile(r'<script type="module">(?:(?!</script>).)*?\.jp-Mermaid(?:(?!</script>).)*</script>', re.S)


def on_post_page(output: str, page, config) -> str:
    return _MERMAID_LOADER.sub("", _EMPTY_SCRIPT.sub("", output))
