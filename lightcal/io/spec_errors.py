"""Where in a project file a pydantic validation error is, in the file's own words
(`lightcal.io.project_spec.parse_project`)."""

from __future__ import annotations

from typing import Any

_UNION_BRANCHES = frozenset({"float", "int", "str", "bool", "list", "dict"})
_TAGS = ("function-", "literal[", "constrained-", "list[")  # pydantic's names of branches


def on_literal_branch(err: Any) -> bool:
    """The error of a union's literal branch ("Input should be 'auto'"), said only when
    no other branch has a more telling one."""
    return any(isinstance(part, str) and part.startswith("literal[") for part in err["loc"])


def format_loc(loc: tuple[Any, ...]) -> str:
    """A pydantic error's location as the file spells it: `images[2].pose.t`, without the
    names pydantic gives a union's branches."""
    out = ""
    for part in loc:
        if isinstance(part, str) and (
            part in _UNION_BRANCHES or part.endswith(("Spec", "Spec]")) or part.startswith(_TAGS)
        ):
            continue  # the name of a union's branch (ExposureSpec, float), not a field
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"
