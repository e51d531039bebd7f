"""Readers of jobs, chosen by file suffix: each turns a file into a path and raw profile settings.

A reader is ``read(name) -> (PathSpec, {"profile": {...}, "interpolator": {...}})``;
the profile sections are raw (validated by :func:`~nurbsinterp.config.job.load_job`,
with the profile file and the command line's overrides on top).  A new input
format (G-code, DXF) registers itself here and touches nothing else.
"""
from __future__ import annotations

import os
from typing import Callable

READERS: dict[str, Callable] = {}  # format name -> reader
SUFFIXES: dict[str, str] = {}  # ".yaml" -> format name
DEFAULT_FORMAT = "yaml"  # a file whose suffix no reader claims is read as a YAML job


def register(fmt: str, suffixes: tuple[str, ...], read: Callable) -> None:
    READERS[fmt] = read
    for suffix in suffixes:
        SUFFIXES[suffix.lower()] = fmt


def reader_for(name: str, input_format: str | None = None) -> Callable:
    if input_format is not None:
        if input_format not in READERS:
            raise ValueError(f"unknown input format {input_format!r} (known: {', '.join(READERS)})")
        return READERS[input_format]
    suffix = os.path.splitext(name)[1].lower()
    return READERS[SUFFIXES.get(suffix, DEFAULT_FORMAT)]


def formats() -> tuple[str, ...]:
    return tuple(READERS)


def _register_builtin() -> None:
    from .job import read_yaml_job

    register("yaml", (".yaml", ".yml"), read_yaml_job)


_register_builtin()
