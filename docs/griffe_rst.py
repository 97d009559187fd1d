"""Griffe extension for the API pages: the docstrings use reStructuredText roles (``:math:``,
``.. math::``, ``:func:`` ...), which mkdocstrings (Markdown) would show verbatim. This turns
them into Markdown before rendering: math into ``$...$`` / ``$$...$$`` (rendered by MathJax
through ``pymdownx.arithmatex``), cross-reference roles into inline code, double back-quotes into
single ones. Loaded by ``mkdocs.yml`` (``extensions: [docs/griffe_rst.py]``)."""

from __future__ import annotations

import re

import griffe

_MATH_ROLE = re.compile(r":math:`([^`]+)`")
_XREF_ROLE = re.compile(r":(?:func|class|meth|mod|data|attr|obj|exc|py:\w+):`~?([^`]+)`")
_DOUBLE = re.compile(r"``([^`]+)``")


def _math_block(text: str) -> str:
    """``.. math:: first line`` plus indented continuation lines -> a ``$$ ... $$`` block."""
    lines, out, i = text.split("\n"), [], 0
    while i < len(lines):
        line = lines[i]
        m = re.match(r"^(\s*)\.\. math::\s*(.*)$", line)
        if not m:
            out.append(line)
            i += 1
            continue
        indent, body = m.group(1), [m.group(2)] if m.group(2).strip() else []
        i += 1
        while i < len(lines) and (not lines[i].strip() or len(lines[i]) - len(lines[i].lstrip()) > len(indent)):
            if lines[i].strip():
                body.append(lines[i].strip())
            elif body:
                # a blank line inside the block ends it only if the next line is not indented
                nxt = lines[i + 1] if i + 1 < len(lines) else ""
                if not nxt.strip() or len(nxt) - len(nxt.lstrip()) <= len(indent):
                    break
            i += 1
        out += ["", f"{indent}$$", *(f"{indent}{b}" for b in body), f"{indent}$$", ""]
    return "\n".join(out)


def rst_to_markdown(text: str) -> str:
    """The conversion applied to every docstring (public for the tests)."""
    text = _math_block(text)
    text = _MATH_ROLE.sub(lambda m: f"${m.group(1)}$", text)
    text = _XREF_ROLE.sub(lambda m: f"`{m.group(1)}`", text)
    return _DOUBLE.sub(lambda m: f"`{m.group(1)}`", text)


class RstToMarkdown(griffe.Extension):
    """Rewrite every docstring once it is loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:  # noqa: D102
        if obj.docstring is not None:
            obj.docstring.value = rst_to_markdown(obj.docstring.value)
