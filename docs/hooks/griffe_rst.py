"""A griffe extension for the docs build (mkdocs.yml loads it; it is not part of qpik).

qpik's docstrings are Google style with a few reStructuredText habits that Markdown does
not know: Sphinx roles (:class:`IKSolver`), a trailing ``::`` before a literal block, and
argument entries that document several names at once (``solver, damping: ...``). This
rewrites them before mkdocstrings parses the docstring: roles become inline code, ``::``
becomes ``:``, and a shared entry becomes one entry per name with the same description.
"""

from __future__ import annotations

import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|data|mod|attr|exc|obj|const|math):`~?([^`]+)`")
LITERAL_BLOCK = re.compile(r"(\S)::\n\n")
SECTION = re.compile(r"^(\s*)(Args|Arguments|Parameters|Keyword Args|Other Parameters):\s*$")
SHARED = re.compile(r"^((?:\*{0,2}\w+,\s*)+\*{0,2}\w+)\s*:\s*(.*)$")


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def split_shared_arguments(text: str) -> str:
    """One argument entry per name where an entry documents several (``a, b: text``)."""
    lines, out, i = text.split("\n"), [], 0
    section_indent = item_indent = None
    while i < len(lines):
        line = lines[i]
        if (match := SECTION.match(line)) is not None:
            section_indent, item_indent = len(match.group(1)), None
            out.append(line)
            i += 1
            continue
        if section_indent is not None and line.strip():
            if _indent(line) <= section_indent:
                section_indent = None
            elif item_indent is None:
                item_indent = _indent(line)
        if section_indent is None or not line.strip() or _indent(line) != item_indent:
            out.append(line)
            i += 1
            continue
        header, j = line.strip(), i + 1
        while header.endswith(",") and j < len(lines) and _indent(lines[j]) > item_indent:
            header, j = f"{header} {lines[j].strip()}", j + 1
        match = SHARED.match(header)
        if match is None:
            out.append(line)
            i += 1
            continue
        rest = []
        while j < len(lines) and (not lines[j].strip() or _indent(lines[j]) > item_indent):
            if not lines[j].strip():
                break
            rest.append(lines[j])
            j += 1
        for name in re.split(r",\s*", match.group(1)):
            out.append(" " * item_indent + f"{name}: {match.group(2)}")
            out.extend(rest)
        i = j
    return "\n".join(out)


def markdown(text: str) -> str:
    """``text`` with Sphinx roles as inline code, ``::`` as ``:``, shared entries split."""
    text = ROLE.sub(lambda m: f"`{m.group(1)}`", text)
    return split_shared_arguments(LITERAL_BLOCK.sub(r"\1:\n\n", text))


class RstRoles(griffe.Extension):
    """Rewrite every docstring before mkdocstrings parses it."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown(obj.docstring.value)
