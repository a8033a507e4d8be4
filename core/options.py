"""The base of every backend's options: :class:`Options`."""

from __future__ import annotations

import types
import typing
from typing import Any

from pydantic import BaseModel, ConfigDict, ValidationInfo, field_validator

__all__ = ["Options", "refuse_bool_for_number"]


def _is_number_field(annotation: Any) -> bool:
    """``int``, ``float`` or an optional one (``float | None``), but not a union with ``bool``."""
    if annotation in (int, float):
        return True
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        args = set(typing.get_args(annotation)) - {type(None)}
        return bool(args) and bool not in args and args <= {int, float}
    return False


def refuse_bool_for_number(model: type[BaseModel], name: str | None, value: Any) -> Any:
    """Refuse ``true``/``false`` for a number field of ``model``: pydantic reads true as 1, which
    in a configuration is always a mistake. Returns ``value`` unchanged otherwise."""
    field = model.model_fields.get(name or "")
    if isinstance(value, bool) and field is not None and _is_number_field(field.annotation):
        raise ValueError(f"expected a number, not {str(value).lower()}")
    return value


class Options(BaseModel):
    """Base of a backend's options, the table ``[<kind>.<backend>]`` of a configuration.

    Subclass it and give every field a docstring under it: ``agrisim plugins --options`` shows
    them, and they are the descriptions of the JSON schema. Unknown keys are refused (a typo is
    an error, not a setting silently ignored), and so is ``true``/``false`` for a number."""

    model_config = ConfigDict(extra="forbid", use_attribute_docstrings=True)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bools_for_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        return refuse_bool_for_number(cls, info.field_name, value)
