"""Griffe extension for geoq's API pages: its docstrings, as Markdown.

geoq's docstrings are reStructuredText-flavoured: ``Parameters`` / ``Attributes`` /
``Returns`` sections whose entries read ``name : what it is`` (a description, not a
type, so no docstring parser fits them), and Sphinx roles (``:class:`~geoq.x.Y```).
Here, before mkdocstrings renders them as plain Markdown (``docstring_style: null``):

* each section becomes a bold title and a list (``- `name`: what it is``);
* each role becomes inline code of its target (``~`` keeps the last name only).

The source docstrings are left as they are (they also read well in ``help()``).
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|data|attr|obj|exc|const):`(~?)([^`]+)`")
_ENTRY = re.compile(r"^(\*{0,2}[A-Za-z_][\w.,\[\] *]*?) : (.*)$")


def _role(match: re.Match[str]) -> str:
    tilde, target = match.groups()
    return f"`{target.rsplit('.', 1)[-1] if tilde else target}`"


def markdown(text: str) -> str:
    """A geoq docstring as Markdown (sections as lists, roles as inline code)."""
    text = _ROLE.sub(_role, text)
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    in_section = False
    while i < len(lines):
        line = lines[i]
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        title = line.strip()
        if title and re.fullmatch(r"-{3,}", nxt.strip()) and not line.startswith(" "):
            out += ["", f"**{title}**", ""]
            in_section = True
            i += 2
            continue
        if in_section:
            entry = _ENTRY.match(line)
            if entry:
                out.append(f"- `{entry[1].strip()}`: {entry[2]}")
            elif line.startswith(" ") and out and out[-1].startswith("- "):
                out[-1] += " " + line.strip()
            elif not line.strip():
                out.append("")
            else:  # prose inside a section (Notes): as it is
                out.append(line)
        else:
            out.append(line)
        i += 1
    return "\n".join(out)


class GeoqDocstrings(griffe.Extension):
    """Rewrites every docstring of the loaded package with :func:`markdown`."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        self._walk(pkg, set())

    def _walk(self, obj: griffe.Object, seen: set[str]) -> None:
        if obj.path in seen:
            return
        seen.add(obj.path)
        if obj.docstring is not None:
            obj.docstring.value = markdown(obj.docstring.value)
        for member in obj.members.values():
            if not member.is_alias:
                self._walk(member, seen)  # type: ignore[arg-type]
