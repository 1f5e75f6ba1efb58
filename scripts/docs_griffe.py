"""Griffe extension for the docs site (mkdocs.yml loads it): makes magsoro's reStructuredText-flavoured
docstrings read well as Markdown.

- Sphinx roles (``:func:`solve```, ``:class:`~magsoro.fields.profiles.Keyframes```) become code spans
  (``solve``, ``Keyframes``): the names stay visible without cross-references that may not resolve.
- ``>>>`` example lines (with their ``...`` continuations and output) become ``pycon`` code blocks instead of
  Markdown block quotes, without their ``# doctest:`` flags.
- Attributes that a method assigns (``self.x = ...`` in ``__init__``) and that carry no docstring are left out:
  they are a class's working state, not its API. Documented ones, and class-level fields (dataclasses,
  pydantic models), stay.

Only the text handed to the docstring parser changes; the source files are not touched.
"""

from __future__ import annotations

import re
from typing import Any

from griffe import Extension

DOCTEST_FLAGS = re.compile(r"#\s*doctest:\s*[+-]\w+(?:\s*,\s*[+-]\w+)*\s*")
ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|attr|data|obj|exc|const|term|ref):`(~?)([^`]+)`")


def _role(match: re.Match) -> str:
    tilde, target = match.groups()
    if "<" in target and target.endswith(">"):  # :ref:`text <target>`
        target = target.split("<", 1)[0].strip()
    if tilde:
        target = target.rsplit(".", 1)[-1]
    return f"`{target}`"


def _fence_examples(text: str) -> str:
    """Wrap runs of ``>>>`` lines (plus ``...`` continuations and output up to a blank line) in a code fence."""
    out, lines, i, in_fence = [], text.splitlines(), 0, False
    while i < len(lines):
        line = lines[i]
        stripped = line.lstrip()
        if stripped.startswith("```"):
            in_fence = not in_fence
        if not in_fence and stripped.startswith(">>>"):
            indent = line[: len(line) - len(stripped)]
            block = []
            while i < len(lines) and lines[i].strip() and lines[i].startswith(indent):
                code = DOCTEST_FLAGS.sub("# ", lines[i][len(indent):]).rstrip()
                block.append(code[:-1].rstrip() if code.endswith("#") else code)
                i += 1
            out += [f"{indent}```pycon", *(indent + b for b in block), f"{indent}```"]
            continue
        out.append(line)
        i += 1
    return "\n".join(out)


def prose_to_markdown(text: str) -> str:
    """The Markdown the site renders for a docstring ``text``."""
    return _fence_examples(ROLE.sub(_role, text))


class ProseDocstrings(Extension):
    """Rewrite every docstring griffe loads with :func:`prose_to_markdown`."""

    def on_instance(self, *, obj: Any, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = prose_to_markdown(obj.docstring.value)

    def on_class_members(self, *, cls: Any, **kwargs: Any) -> None:
        methods = [(m.lineno, m.endlineno) for m in cls.members.values()
                   if not m.is_alias and m.is_function and m.lineno and m.endlineno]
        for name, member in list(cls.members.items()):
            if (not member.is_alias and member.is_attribute and member.docstring is None and member.lineno
                    and any(start <= member.lineno <= end for start, end in methods)):
                cls.del_member(name)
