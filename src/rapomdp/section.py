"""The base of every configuration section (its own module so stage packages can import it)."""

from __future__ import annotations

import types
import typing
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, ValidationInfo, field_validator


def _leaf_types(annotation: Any) -> set[Any]:
    """The plain types an annotation admits (through Optional, unions, lists, tuples)."""
    origin = typing.get_origin(annotation)
    if origin is None:
        return {annotation}
    if origin is typing.Annotated:
        return _leaf_types(typing.get_args(annotation)[0])
    if origin is typing.Literal:
        return {type(value) for value in typing.get_args(annotation)}
    leaves: set[Any] = set()
    for arg in typing.get_args(annotation):
        if arg is not Ellipsis:
            leaves |= _leaf_types(arg)
    if origin not in (typing.Union, types.UnionType, list, tuple):
        leaves.add(origin)
    return leaves


#: Every whole-number field lies within this magnitude (a count of 2^40 views or epochs would
#: only fail later, for memory); a field may bound itself tighter.
MAX_MAGNITUDE = 2**32


def _holds_boolean(value: Any) -> bool:
    if isinstance(value, bool):
        return True
    return isinstance(value, list | tuple) and any(isinstance(v, bool) for v in value)


class Section(BaseModel):
    """A configuration section: unknown keys are errors, assignments are validated, every
    number is finite, and a boolean is never taken as a number (``views: true`` is not 1)."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)

    #: Fields added after workspaces existed, whose default is what those workspaces did:
    #: left out of ``Config.section`` (so of every stage key) while at that default.
    hash_omits_default: ClassVar[tuple[str, ...]] = ()

    @field_validator("*", mode="before")
    @classmethod
    def _no_boolean_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        if info.field_name is None:
            return value
        leaves = _leaf_types(cls.model_fields[info.field_name].annotation)
        if _holds_boolean(value) and bool not in leaves and leaves & {int, float}:
            raise ValueError("a boolean is not a number")
        if (int in leaves and float not in leaves and isinstance(value, int | float)
                and not isinstance(value, bool) and abs(value) >= MAX_MAGNITUDE):
            raise ValueError("a whole number of magnitude below 2^32 is expected")
        return value
