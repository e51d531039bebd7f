"""Reading YAML safely: no duplicate keys, no aliases, a size limit, and a fast path for big files."""
from __future__ import annotations

import os
import re
from typing import Any

import yaml

from ..errors import SpecError
from .units import show

MAX_FILE_BYTES = 64 * 1024 * 1024




class _Loader(yaml.SafeLoader):
    """Safe loading that also refuses aliases and duplicate keys."""

    def compose_node(self, parent, index):  # noqa: D401 - PyYAML hook
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.MarkedYAMLError(problem="YAML aliases (*name) are not allowed in job files",
                                       problem_mark=event.start_mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):
        seen: dict[Any, Any] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                hash(key)
            except TypeError:
                raise yaml.MarkedYAMLError(problem="a mapping key must be a plain value",
                                           problem_mark=key_node.start_mark) from None
            if key in seen:
                raise yaml.MarkedYAMLError(problem=f"duplicate key {show(key)} (first at line {seen[key] + 1})",
                                           problem_mark=key_node.start_mark)
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node):
        # Python refuses int() of more than 4300 digits (a ValueError PyYAML lets through)
        try:
            return super().construct_yaml_int(node)
        except ValueError:
            raise yaml.MarkedYAMLError(problem=f"the integer {show(node.value)} has too many digits",
                                       problem_mark=node.start_mark) from None


_Loader.add_constructor("tag:yaml.org,2002:int", _Loader.construct_yaml_int)


FAST_YAML_BYTES = 1 << 16  # files above this size try the event reader first
_MAX_DEPTH = 64
_PLAIN_INT = re.compile(r"[-+]?(?:0|[1-9][0-9]*)")
_PLAIN_FLOAT = re.compile(r"[-+]?[0-9]+\.[0-9]*(?:[eE][-+][0-9]+)?")
_NO_KEY = object()


class _Unusual(Exception):
    """Something only the full loader reads (or refuses with its message)."""


def _plain_value(value: str, resolver, constructor):
    """A plain scalar as SafeLoader reads it; decimal numbers without the regex resolver."""
    if _PLAIN_INT.fullmatch(value):
        return int(value)  # ValueError past 4300 digits: the full loader words that
    if _PLAIN_FLOAT.fullmatch(value):
        return float(value)
    return constructor.construct_object(yaml.ScalarNode(resolver.resolve(yaml.ScalarNode, value, (True, False)),
                                                        value))


def _fast_yaml(text: str):
    """The document of a plain YAML file, built from libyaml's events.

    A large control net read by the pure-Python loader costs about 0.3 ms a point
    (a minute for 200,000 points); libyaml's events and this builder take a
    hundredth of that.  Only mappings, sequences and untagged scalars are read
    here: an alias, anchor, tag, merge key, duplicate key, second document, deep
    nesting or syntax error raises _Unusual, and the caller reads the file again
    with the full loader, which gives the same result or the usual message.
    """
    from yaml.constructor import SafeConstructor
    from yaml.resolver import Resolver

    resolver, constructor = Resolver(), SafeConstructor()
    stack: list = []  # [container, pending key] of each open collection
    root = None
    documents = 0

    def add(value):
        nonlocal root
        if not stack:
            root = value
            return
        top = stack[-1]
        if isinstance(top[0], list):
            top[0].append(value)
        elif top[1] is _NO_KEY:
            try:
                if value in top[0] or value == "<<":  # a duplicate or a merge key
                    raise _Unusual
            except TypeError:  # an unhashable key
                raise _Unusual from None
            top[1] = value
        else:
            top[0][top[1]] = value
            top[1] = _NO_KEY

    try:
        for event in yaml.parse(text, Loader=yaml.CSafeLoader):
            kind = type(event)
            if kind is yaml.ScalarEvent:
                if event.anchor is not None or event.tag is not None:
                    raise _Unusual
                add(_plain_value(event.value, resolver, constructor) if event.implicit[0] else event.value)
            elif kind is yaml.MappingStartEvent or kind is yaml.SequenceStartEvent:
                if event.anchor is not None or event.tag is not None or len(stack) >= _MAX_DEPTH:
                    raise _Unusual
                stack.append([{} if kind is yaml.MappingStartEvent else [], _NO_KEY])
            elif kind is yaml.MappingEndEvent or kind is yaml.SequenceEndEvent:
                add(stack.pop()[0])
            elif kind is yaml.DocumentStartEvent:
                documents += 1
                if documents > 1:
                    raise _Unusual
            elif kind is yaml.AliasEvent:
                raise _Unusual
    except _Unusual:
        raise
    except Exception:  # noqa: BLE001 - any error: the full loader reads it again and words it
        raise _Unusual from None
    return root


def read_bytes(name: str, what: str) -> bytes:
    """The bytes of the file *name* (a *what*: "YAML file", "program"), at most MAX_FILE_BYTES; every
    failure is a one-line SpecError."""
    try:
        if os.path.isdir(name):
            raise SpecError(f"{name}: is a directory, not a {what}")
        with open(name, "rb") as fh:
            raw = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise SpecError(f"{name}: cannot read: {exc.strerror or exc}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise SpecError(f"{name}: larger than {MAX_FILE_BYTES // 2**20} MiB; refusing to read it")
    return raw


def read_yaml(path: str | os.PathLike) -> dict:
    """Read one YAML mapping from *path*; every failure is a one-line SpecError."""
    name = os.fspath(path)
    raw = read_bytes(name, "YAML file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SpecError(f"{name}: is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start})") from None
    doc = _Unusual
    if len(raw) > FAST_YAML_BYTES and getattr(yaml, "__with_libyaml__", False):
        try:
            doc = _fast_yaml(text)
        except _Unusual:
            pass
    try:
        if doc is _Unusual:
            doc = yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" line {mark.line + 1}, column {mark.column + 1}:" if mark is not None else ""
        problem = " ".join(str(exc.problem or exc.context or "invalid YAML").split())
        raise SpecError(f"{name}:{where} {problem}") from None
    except yaml.YAMLError as exc:
        raise SpecError(f"{name}: invalid YAML: {' '.join(str(exc).split())}") from None
    except RecursionError:
        raise SpecError(f"{name}: YAML nested too deeply") from None
    if doc is None:
        raise SpecError(f"{name}: the file is empty")
    if not isinstance(doc, dict):
        raise SpecError(f"{name}: the document must be a mapping with a 'curve' key, not a {type(doc).__name__}")
    return doc
