"""Configuration files: reading TOML or JSON within bounds, and writing TOML that reads back.

A configuration file is small (the default one is about 2 KB), so reading refuses, before
parsing, a file larger than :data:`MAX_CONFIG_BYTES` or nested deeper than
:data:`MAX_CONFIG_DEPTH` (brackets, braces and dotted keys), each with a message naming the
file and the limit: the parsers would otherwise recurse out of the stack or take memory
quadratic in a dotted key's length.
"""

from __future__ import annotations

import json
import os
import re
import tomllib
from collections.abc import Iterator, Mapping
from typing import Any

from .errors import FidelityError

__all__ = ["MAX_CONFIG_BYTES", "MAX_CONFIG_DEPTH", "read_config", "toml_document"]

#: Largest configuration file read (bytes): about a hundred times the default one, and at most
#: a second or so of parsing.
MAX_CONFIG_BYTES = 1 << 18

#: Deepest nesting of a configuration file: tables, arrays and inline tables within each
#: other, counting each part of a dotted key (``[grades.cuts]`` is 2 deep, its arrays 3).
MAX_CONFIG_DEPTH = 16

_BASIC = r'"(?:\\.|[^"\\\n])*"'
_LITERAL = r"'[^'\n]*'"
_TOML_TOKENS = re.compile(r'"""(?:\\.|[^\\])*?"""|\'\'\'.*?\'\'\'|' + _BASIC + "|" + _LITERAL
                          + r"|#[^\n]*|(?P<open>[\[{])|(?P<close>[\]}])|(?P<dot>\.)", re.S)
_JSON_TOKENS = re.compile(r'"(?:\\.|[^"\\])*"|(?P<open>[\[{])|(?P<close>[\]}])')
_KEY_PART = re.compile(r"\s*(?:[A-Za-z0-9_-]+|" + _BASIC + "|" + _LITERAL + r")\s*")


def _depths(text: str, tokens: re.Pattern) -> Iterator[int]:
    """The nesting depth at each bracket or dotted-key part, strings and comments skipped."""
    depth, chain, last_dot = 0, 0, -1
    for m in tokens.finditer(text):
        if m.group("open"):
            depth += 1
            yield depth
        elif m.group("close"):
            depth = max(0, depth - 1)
        elif m.lastgroup == "dot":
            key_before = last_dot >= 0 and _KEY_PART.fullmatch(text, last_dot, m.start()) is not None
            chain = chain + 1 if key_before else 1
            last_dot = m.end()
            yield depth + chain + 1


def _check_depth(text: str, where: str, kind: str) -> None:
    tokens = _JSON_TOKENS if kind == "JSON" else _TOML_TOKENS
    for depth in _depths(text, tokens):
        if depth > MAX_CONFIG_DEPTH:
            raise FidelityError(f"{where}: the {kind} configuration is nested more than {MAX_CONFIG_DEPTH} levels "
                                "deep; a scoring configuration needs at most 5", option="config")


def _check_structure(data: Any, where: str) -> None:
    """The parsed value's depth (a backstop for what the text scan cannot see)."""
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > MAX_CONFIG_DEPTH:
            raise FidelityError(f"{where}: the configuration is nested more than {MAX_CONFIG_DEPTH} levels deep",
                                option="config")
        if isinstance(value, Mapping):
            stack.extend((v, depth + 1) for v in value.values())
        elif isinstance(value, list):
            stack.extend((v, depth + 1) for v in value)


def _read_bytes(path: str) -> bytes:
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_CONFIG_BYTES + 1)
    except OSError as exc:
        raise FidelityError(f"{path}: cannot read the configuration: {exc.strerror or exc}", option="config") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise FidelityError(f"{path}: larger than {MAX_CONFIG_BYTES} bytes, too large for a scoring configuration",
                            option="config")
    return raw


def read_config(path: str | os.PathLike) -> Any:
    """The parsed content of a ``.toml`` or ``.json`` configuration file (a ``[scoring]``
    table, when there is one), within the size and nesting bounds."""
    spath = os.fsdecode(os.fspath(path))
    kind = "JSON" if spath.lower().endswith(".json") else "TOML"
    raw = _read_bytes(spath)
    try:
        text = raw.decode("utf-8")
        _check_depth(text, spath, kind)
        data = json.loads(text) if kind == "JSON" else tomllib.loads(text)
    except (ValueError, RecursionError) as exc:  # UnicodeDecodeError and the parsers' errors are ValueErrors
        if isinstance(exc, FidelityError):
            raise
        raise FidelityError(f"{spath}: not a valid {kind} configuration: {exc}", option="config") from None
    _check_structure(data, spath)
    return data.get("scoring", data) if isinstance(data, dict) else data


# --------------------------------------------------------------------------- writing
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}


def toml_string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    if any(0xD800 <= ord(c) <= 0xDFFF for c in text):
        raise FidelityError(f"cannot write {text!r} as TOML: it holds a lone surrogate (an undecodable byte); "
                            "save the configuration as JSON")
    escaped = "".join(_ESCAPES.get(c) or (f"\\u{ord(c):04X}" if ord(c) < 0x20 or ord(c) == 0x7F else c)
                      for c in text)
    return f'"{escaped}"'


def toml_key(key: str) -> str:
    """A TOML key: bare when it can be, else a basic (quoted) string."""
    return key if _BARE_KEY.fullmatch(key) else toml_string(key)


def toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise FidelityError(f"cannot write {value!r} as TOML")


def _table(name: str, table: Mapping[str, Any]) -> list[str]:
    lines = ["", f"[{name}]"]
    lines += [f"{toml_key(k)} = {toml_value(v)}" for k, v in table.items() if not isinstance(v, Mapping)]
    for k, v in table.items():
        if isinstance(v, Mapping):
            lines += _table(f"{name}.{toml_key(k)}", v)
    return lines


def toml_document(data: Mapping[str, Any], tables: tuple[str, ...], unset: Mapping[str, str], title: str) -> str:
    """``data`` as a TOML document: plain values first (None as the commented-out example in
    ``unset``), then the ``tables``."""
    lines = [f"# {title}"]
    lines += [f"{toml_key(k)} = {toml_value(v)}" if v is not None else f"# {k} = {unset[k]}"
              for k, v in data.items() if k not in tables]
    for name in tables:
        lines += _table(toml_key(name), data[name])
    return "\n".join(lines) + "\n"
