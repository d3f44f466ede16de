"""One clear sentence for each way a design file can fail to validate.

Pydantic reports a validation error as a location, a type and a message; users need
one sentence naming the file, the key (as written in the file, under its unit alias
if it used one) and what was expected. :class:`SchemaExplainer` turns the first error
into that sentence for any tree of pydantic models; :mod:`printapp.design` configures
it for the design schema.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel


def short_repr(value: Any) -> str:
    """``repr`` of a user's value, cut to 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _describe_range(model: type[BaseModel], name: str) -> str | None:
    info = model.model_fields.get(name)
    if info is None:
        return None
    bounds: dict[str, float] = {}
    for meta in info.metadata:
        for attr in ("gt", "ge", "lt", "le"):
            if hasattr(meta, attr):
                bounds[attr] = getattr(meta, attr)
    annotation = info.annotation
    for arg in getattr(annotation, "__args__", ()):
        for meta in getattr(arg, "__metadata__", ()):
            for attr in ("gt", "ge", "lt", "le"):
                if hasattr(meta, attr):
                    bounds[attr] = getattr(meta, attr)
    if not bounds:
        return None
    lo = (
        "(" + f"{bounds['gt']:g}"
        if "gt" in bounds
        else "[" + f"{bounds['ge']:g}"
        if "ge" in bounds
        else "(-inf"
    )
    hi = (
        f"{bounds['lt']:g}" + ")"
        if "lt" in bounds
        else f"{bounds['le']:g}" + "]"
        if "le" in bounds
        else "inf)"
    )
    return f"{lo}, {hi}"


@dataclass(frozen=True)
class SchemaExplainer:
    """Explains validation errors of ``root``.

    ``tag_field`` names a field holding a tagged union whose members are ``tagged`` (tag ->
    model); pydantic puts the tag into error locations, which the sentence leaves out.
    ``aliases`` maps a file's unit suffix to (internal suffix, factor), as the schema converts.
    """

    root: type[BaseModel]
    tag_field: str
    tagged: dict[str, type[BaseModel]]
    aliases: dict[str, tuple[str, float]]

    def field_info(self, loc: tuple[Any, ...]) -> tuple[type[BaseModel] | None, str | None]:
        """Walk ``loc`` through nested models; return the innermost model and field name."""
        current: type[BaseModel] | None = self.root
        field: str | None = None
        for part in loc:
            if current is None or not isinstance(part, str):
                continue
            if part in self.tagged and field == self.tag_field:
                current = self.tagged[part]
                continue
            if part not in current.model_fields:
                return current, None
            field = part
            annotation = current.model_fields[part].annotation
            nested = [a for a in getattr(annotation, "__args__", (annotation,)) if isinstance(a, type)]
            current = next((a for a in nested if issubclass(a, BaseModel)), None)
            if part == self.tag_field:
                current = None
        return current, field

    def parent_model(self, loc: tuple[Any, ...]) -> type[BaseModel]:
        model, _ = self.field_info(loc[:-1]) if loc else (self.root, None)
        return model if model is not None else self.root

    def key_names(self, model: type[BaseModel]) -> list[str]:
        """The keys a file may use in ``model``'s table, unit aliases included."""
        names = list(model.model_fields)
        for name in list(names):
            for suffix, (internal, _) in self.aliases.items():
                if name.endswith(internal):
                    names.append(name[: -len(internal)] + suffix)
        return names

    def dotted(self, loc: tuple[Any, ...]) -> str:
        parts: list[str] = []
        for part in loc:
            if part in self.tagged and parts and parts[-1] == self.tag_field:
                continue
            if isinstance(part, int):
                if parts:
                    parts[-1] = f"{parts[-1]}[{part}]"
                else:
                    parts.append(f"[{part}]")
            else:
                text = str(part)
                parts.append(text if len(text) <= 40 else text[:37] + "...")
        return ".".join(parts) or "(top level)"

    def alias_used(self, raw: Any, loc: tuple[Any, ...]) -> tuple[str, float, Any] | None:
        """If the file gave ``loc``'s field under a unit alias, return (alias key, factor, raw value)."""
        node = raw
        for part in loc[:-1]:
            if part in self.tagged:
                continue
            if not isinstance(node, dict) or part not in node:
                return None
            node = node[part]
        name = loc[-1] if loc else None
        if not isinstance(node, dict) or not isinstance(name, str) or name in node:
            return None
        for suffix, (internal, factor) in self.aliases.items():
            if name.endswith(internal):
                alias = name[: -len(internal)] + suffix
                if alias in node:
                    return alias, factor, node[alias]
        return None

    def explain(self, error: dict[str, Any], source: str, raw: Any = None) -> str:
        """The sentence for one pydantic error (``exc.errors()`` item) in ``source``."""
        loc = tuple(error["loc"])
        where = self.dotted(loc)
        kind = error["type"]
        alias = self.alias_used(raw, loc)
        if kind == "extra_forbidden":
            parent = self.parent_model(loc)
            key = str(loc[-1])
            close = difflib.get_close_matches(key, self.key_names(parent), n=1, cutoff=0.5)
            hint = (
                f"; did you mean '{close[0]}'?"
                if close
                else f"; valid keys are {', '.join(self.key_names(parent))}"
            )
            return f"{source}: unknown key '{where}'{hint}"
        if kind == "missing":
            return f"{source}: {where}: this key is required"
        if kind in ("union_tag_invalid", "union_tag_not_found"):
            return f'{source}: {where}: expected shape = "tile" or "mesh"'
        value = short_repr(error.get("input"))
        if kind == "value_error":
            msg = str(error.get("ctx", {}).get("error", error["msg"]))
            return f"{source}: {where}: {msg}" if loc else f"{source}: {msg}"
        _, name = self.field_info(loc)
        parent = self.parent_model(loc)
        field_name = name if name is not None else str(loc[-1]) if loc else ""
        if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
            rng = _describe_range(parent, field_name) if loc and isinstance(loc[-1], str) else None
            if rng is None:
                ops = {"gt": ">", "ge": ">=", "lt": "<", "le": "<="}
                bound = " and ".join(f"{ops[k]} {v:g}" for k, v in error.get("ctx", {}).items() if k in ops)
                return f"{source}: {where}: expected a value {bound}, got {value}"
            if alias is not None:
                key, factor, original = alias
                lo, hi = rng.split(", ")
                lo = lo[0] + (f"{float(lo[1:]) / factor:g}" if lo[1:] not in ("-inf",) else lo[1:])
                hi = (f"{float(hi[:-1]) / factor:g}" if hi[:-1] != "inf" else "inf") + hi[-1]
                where = self.dotted(loc[:-1] + (key,))
                return f"{source}: {where}: expected a value in {lo}, {hi}, got {short_repr(original)}"
            return f"{source}: {where}: expected a value in {rng}, got {value}"
        if kind == "finite_number":
            return f"{source}: {where}: expected a finite number, got {value}"
        if kind == "literal_error":
            expected = error.get("ctx", {}).get("expected", "")
            return f"{source}: {where}: expected one of {expected}, got {value}"
        if kind.endswith("_type") or kind.endswith("_parsing") or kind in ("too_short", "too_long"):
            wanted = {
                "float_type": "a number",
                "int_type": "an integer",
                "string_type": "a string",
                "bool_type": "true or false",
                "tuple_type": "an array",
                "model_type": "a table",
                "dict_type": "a table",
                "model_attributes_type": "a table",
                "int_from_float": "an integer",
                "too_short": "a longer value"
                if not isinstance(error.get("input"), (list, tuple))
                else "more items",
                "too_long": "a shorter value"
                if not isinstance(error.get("input"), (list, tuple))
                else "fewer items",
            }.get(kind, error["msg"].lower().replace("input should be ", ""))
            if kind in ("too_short", "too_long") and isinstance(error.get("input"), (list, tuple)):
                n = error.get("ctx", {}).get("min_length", error.get("ctx", {}).get("max_length"))
                if n is not None:
                    wanted = f"an array of {n}"
            return f"{source}: {where}: expected {wanted}, got {value}"
        msg = error["msg"][0].lower() + error["msg"][1:]
        return f"{source}: {where}: {msg}, got {value}"
