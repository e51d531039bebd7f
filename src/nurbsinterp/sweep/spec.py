"""A sweep file: programs x machines x a grid of settings, expanded into cases (issue 31; docs/design/sweep.md).

::

    programs:                                            # paths or globs, relative to this file
      - ../curves/*.yaml
      - {path: ../curves/drawing.dxf, layer: 0}          # or with the reader's options (READER_KEYS)
      - {path: ../curves/pocket.ngc, start: [0, 0, 5]}
    exclude: [../curves/excitation.yaml]
    machines:
      - name: mill
        servo: ../servo/example-xyz.yaml                  # optional: no servo, no simulation
        ini: ../machines/mill.ini                         # optional: a LinuxCNC INI file's limits (plan --machine)
        limits: {x: {max_velocity: 60, max_accel: 800}}   # optional: per axis, as a job's profile.axes; over ini's
    settings: {accel_time: 0.5 s}                         # one value for every case
    grid: {profile: [trapezoidal, adaptive], tolerance: [null, 5 um]}
    timeout: 10 min                                       # optional: a case running longer is stopped, a row

Every case is a program, a machine and one value of each grid key, in the order of the file (programs
outermost, the last grid key fastest); its *fingerprint* hashes what decides its result -- the program's and
the servo file's bytes, the reader's options, the limits and the settings after their units are read -- and
nothing that only labels it (paths, the machine's name, the case's index), so that a renamed machine or a moved program is
not computed again.  Each fault of the file is one line naming it, the field and the value.
"""
from __future__ import annotations

import dataclasses
import glob
import hashlib
import itertools
import json
import os
from typing import Any

from .._version import __version__
from ..config.readers import format_of, reader_point
from ..config.reading import read_bytes, read_yaml
from ..config.rules import Where, choice, mapping, quantity
from ..errors import SpecError
from ..names import ACCDEC, AXES, METHODS, PRECOMPENSATION, PROFILE_TYPES

TOP_KEYS = ("version", "programs", "exclude", "machines", "settings", "grid", "timeout")
MACHINE_KEYS = ("name", "servo", "ini", "limits")
#: a program's reader options (`plan`'s --start, --g28, --g30, --layer, --chain, --chain-tolerance): key -> format
READER_KEYS = {"start": "gcode", "g28": "gcode", "g30": "gcode", "layer": "dxf", "chain": "dxf",
               "chain_tolerance": "dxf"}
FORMAT_NAMES = {"gcode": "G-code programs", "dxf": "DXF drawings", "yaml": "YAML jobs"}
LIMIT_KEYS = {"max_velocity": "feedrate", "max_accel": "accel", "max_jerk": "jerk"}
#: setting -> (kind: a quantity kind, "choice", "bool" or "length-or-null"; the job field it sets, or None)
SETTINGS = {
    "profile": (PROFILE_TYPES, "profile.type"),
    "accdec": (ACCDEC, "profile.accdec"),
    "interpolator": (METHODS, "interpolator.method"),
    "feedrate": ("feedrate", "profile.feedrate"),
    "rapid_feedrate": ("feedrate", "profile.rapid_feedrate"),
    "accel_time": ("time", "profile.accel_time"),
    "period": ("time", "interpolator.period"),
    "max_accel": ("accel", "profile.max_accel"),
    "max_jerk": ("jerk", "profile.max_jerk"),
    "chord_tolerance": ("length", "profile.chord_tolerance"),
    "corner_tolerance": ("length", "profile.corner_tolerance"),
    "tolerance": ("length-or-null", None),  # plan --tolerance: the look-ahead within it (null: as plan decides)
    "precompensate": (("none", *PRECOMPENSATION), None),
}
MAX_CASES = 10 ** 7


@dataclasses.dataclass(frozen=True)
class Program:
    label: str  # its path relative to the sweep file, as written there
    path: str  # resolved, for the client to read
    reader: dict = dataclasses.field(default_factory=dict)  # the reader's options (READER_KEYS), values read


@dataclasses.dataclass(frozen=True)
class Machine:
    name: str
    servo_label: str | None
    servo_path: str | None
    limits: dict  # axis -> {max_velocity, max_accel, max_jerk: mm/s, mm/s², mm/s³}; absent: no limit
    settings: dict = dataclasses.field(default_factory=dict)  # what its INI file sets (rapid_feedrate), below the sweep's
    ini_path: str | None = None  # the LinuxCNC INI file its limits were read from


@dataclasses.dataclass(frozen=True)
class Sweep:
    source: str
    programs: tuple
    machines: tuple
    settings: dict  # key -> value (units read: mm, s)
    grid: dict  # key -> tuple of values
    timeout: float | None = None  # s a case may run before it is stopped (a `timeout` row); None: no limit

    @property
    def size(self) -> int:
        n = len(self.programs) * len(self.machines)
        for values in self.grid.values():
            n *= len(values)
        return n


@dataclasses.dataclass(frozen=True)
class Case:
    """One case, in plain data a worker on another machine can run: the bytes travel, not the paths."""

    index: int
    fingerprint: str
    program: str  # label
    program_bytes: bytes
    program_format: str  # yaml, gcode, dxf
    program_sha256: str
    reader: dict  # the reader's options (READER_KEYS)
    machine: str
    servo_label: str | None
    servo_bytes: bytes | None
    limits: dict
    settings: dict  # every key of SETTINGS the sweep gives, units read
    timeout: float | None = None  # s; not in the fingerprint: a case that finishes gives the same row under any

    def describe(self) -> str:
        """The case's settings for people: ``profile=adaptive tolerance=0.005``."""
        return " ".join(f"{k}={v}" for k, v in self.settings.items())


def reader_text(reader: dict) -> str:
    """A program's reader options as a row gives them: ``layer=CONTOUR start=0,0,5``."""
    return " ".join(f"{k}={','.join(f'{x:g}' for x in v) if isinstance(v, tuple) else v}"
                    for k, v in sorted(reader.items()))


def read_sweep(path) -> Sweep:
    """Read and check a sweep file (module docstring); SpecError naming the file, field and value otherwise."""
    source = os.fspath(path)
    doc = read_yaml(source)
    where = Where(source)
    mapping(where, "", doc, TOP_KEYS)
    if doc.get("version", 1) != 1:
        raise where.fail("version", doc["version"], "is not a sweep file version this nurbsinterp reads (1)")
    base = os.path.dirname(os.path.abspath(source))
    programs = _programs(where, base, doc.get("programs"), doc.get("exclude") or [])
    machines = _machines(where, base, doc.get("machines"))
    settings = {key: _setting(where, f"settings.{key}", key, value)
                for key, value in mapping(where, "settings", doc.get("settings") or {}, tuple(SETTINGS)).items()}
    grid = {}
    for key, values in mapping(where, "grid", doc.get("grid") or {}, tuple(SETTINGS)).items():
        if not isinstance(values, list) or not values:
            raise where.fail(f"grid.{key}", values, "must be a non-empty list of values")
        if key in settings:
            raise where.fail(f"grid.{key}", values, "is also in settings: give it in one of them")
        grid[key] = tuple(_setting(where, f"grid.{key}[{i}]", key, v) for i, v in enumerate(values))
    timeout = None
    if doc.get("timeout") is not None:
        timeout = quantity(where, "timeout", doc["timeout"], "time")
    sweep = Sweep(source, programs, machines, settings, grid, timeout)
    if sweep.size > MAX_CASES:
        raise SpecError(f"{source}: {sweep.size} cases, more than the {MAX_CASES:g} a sweep may have")
    pre = [v for v in (settings.get("precompensate"), *grid.get("precompensate", ())) if v not in (None, "none")]
    bare = [m.name for m in machines if m.servo_path is None]
    if pre and bare:
        raise SpecError(f"{source}: precompensate {pre[0]} needs a servo model, and machine {bare[0]!r} has none")
    return sweep


def _programs(where, base, given, exclude) -> tuple:
    if not isinstance(given, list) or not given or not all(isinstance(p, (str, dict)) and p for p in given):
        raise where.fail("programs", given, "must be a non-empty list of paths or globs (or {path: ..., options})")
    if not isinstance(exclude, list) or not all(isinstance(p, str) for p in exclude):
        raise where.fail("exclude", exclude, "must be a list of paths or globs")
    dropped = {os.path.normpath(p) for e in exclude for p in _matches(base, e)}
    out, seen = [], set()
    for i, entry in enumerate(given):
        at = f"programs[{i}]"
        pattern, options = entry, {}
        if isinstance(entry, dict):
            mapping(where, at, entry, ("path", *READER_KEYS))
            pattern = entry.get("path")
            if not isinstance(pattern, str) or not pattern:
                raise where.fail(f"{at}.path", pattern, "must be a path or a glob")
            options = {k: v for k, v in entry.items() if k != "path"}
        found = _matches(base, pattern)
        if not found:
            raise where.fail(at if not options else f"{at}.path", pattern, f"matches no file (relative to {base})")
        reader = {key: _reader_option(where, f"{at}.{key}", key, value) for key, value in options.items()
                  if value is not None}
        for path in found:
            path = os.path.normpath(path)
            fmt = format_of(path, None)
            for key in reader:
                if READER_KEYS[key] != fmt:
                    raise where.fail(f"{at}.{key}", options[key], f"applies to {FORMAT_NAMES[READER_KEYS[key]]}, and "
                                     f"{os.path.relpath(path, base)} is one of the "
                                     f"{FORMAT_NAMES.get(fmt, fmt + ' files')}")
            key = (path, json.dumps(reader, sort_keys=True))
            if key in seen or path in dropped:
                continue
            seen.add(key)
            label = path if os.path.isabs(os.path.expanduser(pattern)) else os.path.relpath(path, base)
            out.append(Program(label.replace(os.sep, "/"), path, reader))
    if not out:
        raise where.fail("programs", given, "leaves no program once exclude is taken away")
    return tuple(out)


def _reader_option(where, name, key, value):
    """A reader option as the reader takes it: --start's X,Y[,Z] (and --g28's, --g30's X,Y,Z) as a tuple of mm,
    --layer a name, --chain a number from 1, --chain-tolerance a length."""
    if key in ("start", "g28", "g30"):
        numbers = reader_point(value, (2, 3) if key == "start" else (3,))
        if numbers is None:
            raise where.fail(name, value, f"must be {'X,Y or X,Y,Z' if key == 'start' else 'X,Y,Z'} in mm "
                                          f"(for example [0, 0, 5])")
        return numbers
    if key == "layer":
        if not isinstance(value, (str, int)) or isinstance(value, bool) or not str(value):
            raise where.fail(name, value, "must be a layer's name")
        return str(value)
    if key == "chain":
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise where.fail(name, value, "must be a chain's number, from 1")
        return value
    return quantity(where, name, value, "length", zero_ok=True)  # chain_tolerance


def _matches(base, pattern) -> list:
    full = os.path.join(base, os.path.expanduser(pattern))
    if glob.has_magic(pattern):
        return sorted(p for p in glob.glob(full, recursive=True) if os.path.isfile(p))
    return [full] if os.path.isfile(full) else []


def _machines(where, base, given) -> tuple:
    if not isinstance(given, list) or not given:
        raise where.fail("machines", given, "must be a non-empty list of machines (name, servo, limits)")
    out, names = [], set()
    for i, m in enumerate(given):
        at = f"machines[{i}]"
        mapping(where, at, m, MACHINE_KEYS)
        name = m.get("name")
        if not isinstance(name, str) or not name.strip():
            raise where.fail(f"{at}.name", name, "must be a name")
        if name in names:
            raise where.fail(f"{at}.name", name, "is the name of another machine")
        names.add(name)
        servo = m.get("servo")
        servo_path = None
        if servo is not None:
            if not isinstance(servo, str):
                raise where.fail(f"{at}.servo", servo, "must be the path of a servo model file")
            servo_path = os.path.normpath(os.path.join(base, servo))
            if not os.path.isfile(servo_path):
                raise where.fail(f"{at}.servo", servo, f"is not a file (relative to {base})")
            from ..servo import load_servo

            load_servo(servo_path)  # a bad model is the sweep file's fault: refused before any case runs
        limits, settings, ini_path = {}, {}, None
        ini = m.get("ini")
        if ini is not None:  # as plan --machine reads it: the axes' limits, G0 at the traj's largest velocity
            if not isinstance(ini, str):
                raise where.fail(f"{at}.ini", ini, "must be the path of a LinuxCNC INI file")
            ini_path = os.path.normpath(os.path.join(base, ini))
            if not os.path.isfile(ini_path):
                raise where.fail(f"{at}.ini", ini, f"is not a file (relative to {base})")
            from ..config.machine_ini import read_machine

            try:
                machine = read_machine(ini_path)
            except SpecError as exc:  # its file and line, and where the sweep names it
                raise SpecError(f"{where.default}: {at}.ini: {exc}") from None
            for axis in machine.axes:
                limits[axis.axis] = {"max_velocity": axis.max_velocity.value, "max_accel": axis.max_accel.value,
                                     **({"max_jerk": axis.max_jerk.value} if axis.max_jerk is not None else {})}
            if machine.max_linear_velocity is not None:
                settings["rapid_feedrate"] = machine.max_linear_velocity.value
        for axis, values in mapping(where, f"{at}.limits", m.get("limits") or {}, AXES).items():
            fields = mapping(where, f"{at}.limits.{axis}", values, tuple(LIMIT_KEYS))
            limits.setdefault(axis, {}).update({k: quantity(where, f"{at}.limits.{axis}.{k}", v, LIMIT_KEYS[k])
                                                for k, v in fields.items() if v is not None})
        out.append(Machine(name, servo, servo_path, {a: v for a, v in limits.items() if v}, settings, ini_path))
    return tuple(out)


def _setting(where, name, key, value) -> Any:
    kind, _ = SETTINGS[key]
    if isinstance(kind, tuple):
        return choice(where, name, value, kind)
    if kind == "length-or-null":
        return None if value is None else quantity(where, name, value, "length", zero_ok=True)
    return quantity(where, name, value, kind)


def cases(sweep: Sweep, read=read_bytes):
    """The sweep's cases in order (module docstring), each with its program's and servo's bytes (*read*: a
    callable (path, what) -> bytes).  A lazy generator: one program's bytes are held at a time."""
    servos = {m.name: None if m.servo_path is None else read(m.servo_path, "servo model") for m in sweep.machines}
    keys = list(sweep.grid)
    index = 0
    for program in sweep.programs:
        data = read(program.path, "program")
        fmt = format_of(program.path, None)
        digest = hashlib.sha256(data).hexdigest()
        for machine in sweep.machines:
            servo = servos[machine.name]
            for values in itertools.product(*sweep.grid.values()):
                settings = {**machine.settings, **sweep.settings, **dict(zip(keys, values))}
                yield Case(index, fingerprint(digest, fmt, servo, machine.limits, settings, program.reader),
                           program.label, data, fmt, digest, program.reader, machine.name, machine.servo_label,
                           servo, machine.limits, settings, sweep.timeout)
                index += 1


def fingerprint(program_sha256: str, program_format: str, servo: bytes | None, limits: dict, settings: dict,
                reader: dict | None = None) -> str:
    """32 hex digits: the hash of what decides a case's result (module docstring), nulls dropped."""
    doc = {"format": 1, "nurbsinterp": __version__, "program": program_sha256, "program_format": program_format,
           "reader": {k: list(v) if isinstance(v, tuple) else v for k, v in sorted((reader or {}).items())},
           "servo": None if servo is None else hashlib.sha256(servo).hexdigest(),
           "limits": {a: {k: float(v) for k, v in sorted(lim.items())} for a, lim in sorted(limits.items())},
           "settings": {k: (float(v) if isinstance(v, (int, float)) else v) for k, v in sorted(settings.items())
                        if v is not None}}
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:32]
