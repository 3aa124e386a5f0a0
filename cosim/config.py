"""Plain YAML data -> a tree of frozen dataclasses, with errors naming file and key.

Unknown keys, wrong types and out-of-range values (``ValueError`` raised by a
dataclass's ``__post_init__``) all become :class:`ScenarioError` lines of the form
``<file>: <key.path>: <what was expected>``.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from enum import StrEnum
from pathlib import Path
from typing import Any, Literal, TypeVar, get_args, get_origin, get_type_hints

import yaml

from cosim.errors import ScenarioError
from networks.errors import quoted

T = TypeVar("T")


def read_yaml(path: Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise ScenarioError(f"{path}: cannot read: {err.strerror}") from err
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise ScenarioError(f"{path}: not valid YAML{where}: {getattr(err, 'problem', err)}") from err
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ScenarioError(f"{path}: expected a mapping of keys at the top level, got {type(data).__name__}")
    return data


def build(cls: type[T], data: Any, source: str, key: str = "") -> T:
    """Validate ``data`` against dataclass ``cls``."""
    return typing.cast(T, _convert(cls, data, source, key))


def _type_name(tp: Any) -> str:
    if get_origin(tp) is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(tp))
    if isinstance(tp, type) and issubclass(tp, StrEnum):
        return "one of " + ", ".join(repr(m.value) for m in tp)
    return getattr(tp, "__name__", str(tp))


def _fail(source: str, key: str, expected: str, got: Any) -> ScenarioError:
    shown = quoted(got) if not isinstance(got, dict | list) else type(got).__name__
    return ScenarioError(f"{source}: {key or '<top>'}: expected {expected}, got {shown}")


def _convert(tp: Any, value: Any, source: str, key: str) -> Any:
    origin = get_origin(tp)
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return _dataclass(tp, value, source, key)
    if origin in (typing.Union, types.UnionType):
        options = get_args(tp)
        if value is None and type(None) in options:
            return None
        inner = [o for o in options if o is not type(None)]
        for option in inner[:-1]:  # the first type the value fits; the last one's error otherwise
            try:
                return _convert(option, value, source, key)
            except ScenarioError:
                continue
        return _convert(inner[-1], value, source, key)
    if origin is Literal:
        if value not in get_args(tp):
            raise _fail(source, key, _type_name(tp), value)
        return value
    if origin in (tuple, list):
        args = get_args(tp)
        if not isinstance(value, list | tuple):
            raise _fail(source, key, "a list", value)
        if origin is tuple and len(args) > 0 and args[-1] is not Ellipsis:
            if len(value) != len(args):
                raise _fail(source, key, f"a list of {len(args)} values", value)
            return tuple(
                _convert(a, v, source, f"{key}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True))
            )
        item = args[0] if args else Any
        return tuple(_convert(item, v, source, f"{key}[{i}]") for i, v in enumerate(value))
    if origin is dict:
        key_t, val_t = get_args(tp)
        if not isinstance(value, dict):
            raise _fail(source, key, "a mapping", value)
        return {
            _convert(key_t, k, source, f"{key}.{k}"): _convert(val_t, v, source, f"{key}.{k}") for k, v in value.items()
        }
    return _scalar(tp, value, source, key)


def _scalar(tp: Any, value: Any, source: str, key: str) -> Any:
    if tp is Any:
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise _fail(source, key, "true or false", value)
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise _fail(source, key, "a whole number", value)
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise _fail(source, key, "a number", value)
        if not math.isfinite(value):
            raise _fail(source, key, "a finite number", value)
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise _fail(source, key, "a string", value)
        return value
    if isinstance(tp, type) and issubclass(tp, StrEnum):  # a word of a closed set (networks.vocabulary)
        if not isinstance(value, str) or value not in tp._value2member_map_:
            raise _fail(source, key, _type_name(tp), value)
        return tp(value)
    raise _fail(source, key, _type_name(tp), value)


def _dataclass(cls: type, value: Any, source: str, key: str) -> Any:
    if not isinstance(value, dict):
        raise _fail(source, key, f"a mapping of {cls.__name__} keys", value)
    hints = get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(value) - set(fields))
    if unknown:
        where = f"{key}.{unknown[0]}" if key else str(unknown[0])
        known = ", ".join(sorted(fields))
        raise ScenarioError(f"{source}: {where}: unknown key (known keys here: {known})")
    kwargs = {name: _convert(hints[name], value[name], source, f"{key}.{name}" if key else name)
              for name in fields if name in value}  # fmt: skip
    missing = [
        n
        for n, f in fields.items()
        if n not in kwargs and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        where = f"{key}.{missing[0]}" if key else missing[0]
        raise ScenarioError(f"{source}: {where}: required key is missing")
    try:
        return cls(**kwargs)
    except ValueError as err:
        raise ScenarioError(f"{source}: {_where(key, str(err), fields)}") from err


def _where(key: str, message: str, fields: dict[str, Any]) -> str:
    """``key.field: ...`` when the message starts with one of the dataclass's fields."""
    head = message.split(":", 1)[0].split(".", 1)[0].split("[", 1)[0]
    if head in fields:
        return f"{key}.{message}" if key else message
    return f"{key}: {message}" if key else message


def set_override(data: dict[str, Any], assignment: str, source: str = "--set") -> None:
    """Apply ``a.b.c=value`` (value parsed as YAML) to a nested mapping in place."""
    if "=" not in assignment:
        raise ScenarioError(f"{source}: {quoted(assignment)}: expected key=value")
    dotted, raw = assignment.split("=", 1)
    parts = [p for p in dotted.strip().split(".") if p]
    if not parts:
        raise ScenarioError(f"{source}: {quoted(assignment)}: expected key=value")
    try:
        value = yaml.safe_load(raw)
    except yaml.YAMLError as err:
        raise ScenarioError(f"{source}: {dotted}: value {quoted(raw)} is not valid YAML") from err
    node = data
    for part in parts[:-1]:
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise ScenarioError(f"{source}: {dotted}: {part} is not a mapping")
        node = child
    node[parts[-1]] = value
