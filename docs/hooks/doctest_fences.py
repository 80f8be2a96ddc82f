"""Griffe extension for the API pages: doctests render as code, Sphinx roles as plain code.

hmodel's docstrings carry short doctests (``>>> ...`` lines and their expected output) anywhere
in the text, not only under an "Examples" section. In Markdown a ``>>>`` line is a nested
block quote and an output such as ``[45, 55]`` a reference link, so each doctest block (from its
first ``>>>`` line to the next blank line) is wrapped in a ``pycon`` fence before mkdocstrings
renders the docstring; Sphinx roles such as ``:func:`name``` (which mkdocstrings does not read)
become ``name`` in code. Registered in ``mkdocs.yml`` under the Python handler's
``extensions``.
"""

from __future__ import annotations

import re

import griffe


_ROLE = re.compile(r":(?:func|class|meth|mod|data|attr|exc|obj|const):`~?([^`]+)`")


def fence_doctests(text: str) -> str:
    r"""``text`` with every bare doctest block fenced as ``pycon`` and Sphinx roles
    (``:func:`name```) as plain code; fenced code is left alone.

    >>> fence_doctests("Add, see :func:`f`:\n\n>>> 1 + 1\n2\n\nDone.").splitlines()
    ['Add, see `f`:', '', '```pycon', '>>> 1 + 1', '2', '```', '', 'Done.']
    """
    out: list[str] = []
    lines = text.splitlines()
    fenced = False
    i = 0
    while i < len(lines):
        line = lines[i]
        stripped = line.lstrip()
        if stripped.startswith(("```", "~~~")):
            fenced = not fenced
        if fenced or not stripped.startswith(">>>"):
            out.append(line if fenced else _ROLE.sub(r"`\1`", line))
            i += 1
            continue
        indent = line[: len(line) - len(stripped)]
        out.append(f"{indent}```pycon")
        while i < len(lines) and lines[i].strip():
            out.append(lines[i])
            i += 1
        out.append(f"{indent}```")
    return "\n".join(out)


class DoctestFences(griffe.Extension):
    """Fence the doctest blocks of every docstring griffe loads."""

    def on_instance(self, *, obj, **kwargs) -> None:  # noqa: D102
        if obj.docstring is not None:
            obj.docstring.value = fence_doctests(obj.docstring.value)
