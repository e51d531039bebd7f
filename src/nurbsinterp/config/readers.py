"""Readers of jobs, chosen by file suffix: each turns a file into a path and raw profile settings.

A reader is ``read(name, **options) -> (PathSpec, {"profile": {...}, "interpolator": {...}})``;
the profile sections are raw (validated by :func:`~nurbsinterp.config.job.load_job`,
with the profile file and the command line's overrides on top).  *options* are the
reader's own settings (``start`` for G-code; ``layer``, ``chain``, ``chain_tolerance``
for DXF), None where not given; a reader takes every option any reader takes and
uses its own.  A new input format registers itself here and touches nothing else.
"""
from __future__ import annotations

import os
from typing import Callable

READERS: dict[str, Callable] = {}  # format name -> reader
OUTLINES: dict[str, Callable] = {}  # format name -> what `info` lists of a file beyond its path (a drawing's chains)
#: format name -> a reader that hands on the path's blocks as it reads them (a long program never held whole):
#: ``read(name, **options) -> (a stream with dim, has_rapids, fingerprint, items(), notes, {})``
STREAMS: dict[str, Callable] = {}
SUFFIXES: dict[str, str] = {}  # ".yaml" -> format name
DEFAULT_FORMAT = "yaml"  # a file whose suffix no reader claims is read as a YAML job


def register(fmt: str, suffixes: tuple[str, ...], read: Callable, outline: Callable | None = None,
             stream: Callable | None = None) -> None:
    READERS[fmt] = read
    if outline is not None:
        OUTLINES[fmt] = outline
    if stream is not None:
        STREAMS[fmt] = stream
    for suffix in suffixes:
        SUFFIXES[suffix.lower()] = fmt


def reader_for(name: str, input_format: str | None = None, stream: bool = False) -> Callable:
    """The reader of the file; with *stream*, the format's streaming reader where it has one."""
    if input_format is not None and input_format not in READERS:
        raise ValueError(f"unknown input format {input_format!r} (known: {', '.join(READERS)})")
    fmt = format_of(name, input_format)
    return STREAMS[fmt] if stream and fmt in STREAMS else READERS[fmt]


def format_of(name: str, input_format: str | None = None) -> str:
    """The format a file is read as: *input_format*, or the one its suffix names (YAML by default)."""
    return input_format or SUFFIXES.get(os.path.splitext(name)[1].lower(), DEFAULT_FORMAT)


def outline_for(name: str, input_format: str | None = None) -> Callable | None:
    """``outline(name, **options) -> {"chains": [...]}`` for a format that has one, else None."""
    return OUTLINES.get(format_of(name, input_format))


def reader_point(value, sizes: tuple[int, ...]) -> tuple[float, ...] | None:
    """A G-code reader's point (its start, G28, G30 position): ``"X,Y,Z"`` (an option's text) or a list of numbers
    (a sweep file's), in mm, as a tuple of floats; None where it is not *sizes* finite numbers."""
    parts = value.split(",") if isinstance(value, str) else value
    if not isinstance(parts, list) or any(isinstance(x, bool) for x in parts):
        return None
    try:
        numbers = tuple(float(x) for x in parts)
    except (TypeError, ValueError):
        return None
    if len(numbers) not in sizes or not all(abs(x) < float("inf") for x in numbers):
        return None  # nan fails the comparison too
    return numbers


def formats() -> tuple[str, ...]:
    return tuple(READERS)


def _lazy(module: str, function: str) -> Callable:
    """A reader imported when first used: `nurbsinterp plan job.yaml` never loads ezdxf."""

    def read(name, **options):
        import importlib

        return getattr(importlib.import_module(module, __package__), function)(name, **options)

    return read


def _register_builtin() -> None:
    register("yaml", (".yaml", ".yml"), _lazy(".job", "read_yaml_job"))
    register("gcode", (".ngc", ".nc", ".gcode", ".tap", ".cnc"), _lazy(".gcode", "read_gcode_job"),
             stream=_lazy(".gcode", "stream_gcode_job"))
    register("dxf", (".dxf",), _lazy(".dxf", "read_dxf_job"), _lazy(".dxf", "dxf_outline"))


_register_builtin()
