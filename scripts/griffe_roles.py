"""A griffe extension for the site's API pages (mkdocs.yml): agrisim's docstrings name code with
reST roles and double backticks, as Sphinx reads them; mkdocstrings renders Markdown, so each
``:class:`~agrisim.a.B``` and each ````x```` becomes inline code (``agrisim.a.B``, ``x``)."""

from __future__ import annotations

import re
from typing import Any

from griffe import Extension

ROLE = re.compile(r":(?:class|meth|func|mod|attr|data|exc):`~?([^`]+)`")
LITERAL = re.compile(r"``([^`]+)``")


def markdown(text: str) -> str:
    """``text`` with reST roles and double-backtick literals as Markdown code, and a
    paragraph's closing ``::`` as one colon."""
    text = LITERAL.sub(r"`\1`", ROLE.sub(r"`\1`", text))
    return re.sub(r"(?<=\S)::$", ":", text, flags=re.M)  # reST's "::" before a literal block


class RolesToMarkdown(Extension):
    """Rewrites every docstring once its object exists (see the module)."""

    def on_instance(self, *, obj: Any, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown(obj.docstring.value)
