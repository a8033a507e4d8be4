"""Reading a run directory back: its JSON documents, checked, with one-line errors.

``run.json`` and ``cameras.json`` are agrisim's own files, but a directory given on the command
line may be anything: every reader here turns a missing, unreadable or malformed document into
a :class:`agrisim.errors.UserError` (or the subclass the caller names) that says which file and
why.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from agrisim.errors import UserError


def read_json(path: Path, missing: str, error: type[UserError] = UserError, prefix: str = "") -> dict[str, Any]:
    """The JSON object in ``path``. A missing file is reported as ``<dir> holds no <name>:
    <missing>``; an unreadable or non-object one names the file. ``prefix`` starts every
    message (``"--resume: "``)."""
    if not path.is_file():
        raise error(f"{prefix}{path.parent} holds no {path.name}: {missing}")
    try:
        doc = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise error(f"{prefix}cannot read {path}: {exc}") from None
    if not isinstance(doc, dict):
        raise error(f"{prefix}{path} is not a JSON object")
    return doc
