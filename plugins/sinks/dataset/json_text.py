"""Pretty JSON text (what ``json.dumps(obj, indent=2)`` writes) of documents that are rewritten
as they grow, such as ``run.json`` after every setpoint: the members of their long arrays and
objects are encoded once and their text spliced into every later rewrite.

Python's JSON encoder runs in pure Python whenever it indents, so re-encoding a growing list at
every step costs time in the square of its length (hundreds of setpoints: seconds). Splicing
gives the very same bytes: a member nested ``L`` levels deep is its own pretty text with every
line break followed by ``L`` more indents.
"""

from __future__ import annotations

import json
import secrets
from collections.abc import Callable, Hashable, Mapping, Sequence
from typing import Any

INDENT = "  "


class Spliced:
    """An array or object of already encoded members, to stand in a document given to
    :func:`dumps` (made by :meth:`MemberCache.array` and :meth:`MemberCache.object`)."""

    def __init__(self, members: list[tuple[str | None, str]], is_object: bool) -> None:
        self.members = members  # (key, or None in arrays; pretty text at level 0)
        self.is_object = is_object

    def text(self, level: int) -> str:
        """This array's or object's text where it opens at nesting ``level``."""
        if not self.members:
            return "{}" if self.is_object else "[]"
        inner = "\n" + INDENT * (level + 1)
        parts = []
        for key, text in self.members:
            body = text.replace("\n", inner)
            parts.append(inner + (json.dumps(key) + ": " + body if key is not None else body))
        close = "\n" + INDENT * level + ("}" if self.is_object else "]")
        return ("{" if self.is_object else "[") + ",".join(parts) + close


class MemberCache:
    """The pretty text of each member of one growing array or object, encoded again only when
    the member's value changes (values are compared, so a mutated member is never stale)."""

    def __init__(self, default: Callable[[Any], Any] | None = None) -> None:
        self.default = default
        self._texts: dict[Hashable, tuple[Any, str]] = {}

    def text(self, key: Hashable, value: Any) -> str:
        """``json.dumps(value, indent=2)``, from the cache when ``value`` equals the last one
        seen under ``key``."""
        cached = self._texts.get(key)
        if cached is not None and cached[0] == value:
            return cached[1]
        text = json.dumps(value, indent=2, default=self.default)
        self._texts[key] = (value, text)
        return text

    def array(self, values: Sequence[Any]) -> Spliced:
        """``values`` as a JSON array (members cached by position)."""
        return Spliced([(None, self.text(i, v)) for i, v in enumerate(values)], is_object=False)

    def object(self, items: Mapping[str, Any]) -> Spliced:
        """``items`` as a JSON object, in their order (members cached by key)."""
        return Spliced([(k, self.text(k, v)) for k, v in items.items()], is_object=True)


def dumps(doc: Any, default: Callable[[Any], Any] | None = None) -> str:
    """``json.dumps(doc, indent=2, default=default)``, with every :class:`Spliced` in ``doc``
    written as the array or object it stands for."""
    spliced: dict[str, Spliced] = {}
    # A token no real string can hold: JSON escapes the NUL it starts with.
    token = "\0" + secrets.token_hex(8) + "-"

    def stand_in(obj: Any) -> Any:
        if isinstance(obj, Spliced):
            name = f"{token}{len(spliced)}"
            spliced[name] = obj
            return name
        if default is None:
            raise TypeError(f"Object of type {type(obj).__name__} is not JSON serializable")
        return default(obj)

    text = json.dumps(doc, indent=2, default=stand_in)
    for name, value in spliced.items():
        quoted = json.dumps(name)
        at = text.index(quoted)
        # The stand-in sits on the line of its key (or alone, in an array): that line's
        # indent is the level the array or object opens at.
        start = end = text.rfind("\n", 0, at) + 1
        while text[end] == " ":
            end += 1
        level = (end - start) // len(INDENT)
        text = text[:at] + value.text(level) + text[at + len(quoted) :]
    return text
