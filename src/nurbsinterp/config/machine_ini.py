"""A LinuxCNC INI file read as the machine's limits (``--machine FILE.ini``).

What is read, per axis X, Y, Z (LinuxCNC 2.8 and later name the axes' sections by letter)::

    [AXIS_X]  MAX_VELOCITY       machine units/s        -> profile.axes.x.max_velocity, mm/s
              MAX_ACCELERATION   machine units/s²       -> profile.axes.x.max_accel, mm/s²
              MAX_JERK           machine units/s³       -> profile.axes.x.max_jerk, mm/s³ (the look-ahead only)
              OFFSET_AV_RATIO    share kept for external offsets: the planner gets (1 - ratio) of the two above
    [TRAJ]    LINEAR_UNITS       mm | metric | in | inch | imperial, or a number: machine units per mm
              MAX_LINEAR_VELOCITY  machine units/s    -> profile.rapid_feedrate (what G0 moves run at in LinuxCNC)
    [EMCMOT]  SERVO_PERIOD       ns                     reported, not applied (the period is the job's)
    [KINS]    KINEMATICS, JOINTS                        for the [JOINT_n] fallback below

The file's rules, as LinuxCNC's reader has them (``src/emc/ini/inifile.cc`` of LinuxCNC master, 2026, and the
older ``src/libnml/inifile/inifile.cc`` of 2.9, and the INI chapter of the manual, ``docs/src/config/ini-config.adoc``):

- a line whose first non-blank character is ``#`` or ``;`` is a comment; a line ending in ``\\`` continues on the
  next (the joined line is named by its first line here);
- ``[NAME]`` opens a section; names of sections and variables are case-sensitive;
- ``NAME = VALUE``, blanks around the ``=`` and at the ends of the value ignored;
- a variable given twice in a section: the FIRST is used (both readers' ``Find(tag, section, num=1)``; the manual:
  "the first one encountered will be used").  A section given twice: master merges them (with a warning), 2.9
  searched only the first; here they are merged, so a variable of the second counts only where the first lacks it;
- ``#`` and ``;`` after a value are not comments for master's reader ("INCORRECT = value # and this is not a
  comment"), but its number conversion (strtod) stops at them with a warning, and 2.9's sscanf("%lf") silently:
  a number followed by blanks and such a comment is read as the number here too; any other trailing text is refused;
- ``#INCLUDE file`` (master's reader; 2.9's start-up script expanded it) reads another file in its place, relative
  to the including file's directory.

A number is what C's strtod takes in decimal (sign, digits, point, exponent); nan, inf and hexadecimal floats are
refused.  LINEAR_UNITS as a number is read as 2.9 reads it, units per mm (master takes only the names).

When [AXIS_X] lacks MAX_VELOCITY or MAX_ACCELERATION, LinuxCNC uses 1 unit/s (or /s²), a default no machine
means; such a file is a LinuxCNC 2.7 file brought half-way, or a machine whose axis limits are its joints'.  Those
are taken from the joints only for ``trivkins`` (identity kinematics: each joint IS its axis): the joints of the
letter in its ``coordinates=`` (default ``XYZABCUVW``, only the first ``[KINS] JOINTS``), the lowest of them where
a letter has several (a gantry's joints move together).  For other kinematics the value is refused: the joints'
limits do not say the axes'.

Every problem is one :class:`~nurbsinterp.errors.SpecError` line naming the file and line, the section, the
variable and its value: ``machine.ini:12: [AXIS_X] MAX_ACCELERATION = 'abc' is not a number``.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

from ..errors import SpecError

#: the axes read (the path's)
AXIS_LETTERS = ("X", "Y", "Z")
#: [TRAJ] LINEAR_UNITS by name -> mm per machine unit (LinuxCNC's mapLinearUnits, caseless)
LINEAR_UNITS = {"mm": 1.0, "metric": 1.0, "in": 25.4, "inch": 25.4, "imperial": 25.4}
TRIVKINS_COORDINATES = "XYZABCUVW"  # trivkins.c's default coordinates=
MAX_INCLUDE_DEPTH = 16  # as LinuxCNC's reader
MAX_OFFSET_AV_RATIO = 0.9  # iniaxis.cc: a ratio outside [0, 0.9] is an error there (it substitutes 0.1)

# strtod's decimal numbers; the rest of the value may be blanks and a comment
_NUMBER = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_TRAILING_COMMENT = re.compile(r"^(?:\s+[#;].*)?$")


@dataclass(frozen=True)
class Entry:
    """One ``NAME = VALUE`` of the file: the value as written and where (file, line)."""

    section: str
    name: str
    value: str
    file: str
    line: int

    @property
    def where(self) -> str:
        """``machine.ini:12: [AXIS_X] MAX_VELOCITY``: how messages and notes name it."""
        return f"{self.file}:{self.line}: [{self.section}] {self.name}"


@dataclass(frozen=True)
class Limit:
    """A limit in mm and s (mm/s, mm/s², mm/s³, or s), and where it was read (``file:line: [SECTION] NAME``)."""

    value: float
    where: str


@dataclass(frozen=True)
class AxisLimits:
    axis: str  # 'x', 'y', 'z'
    max_velocity: Limit  # mm/s, (1 - OFFSET_AV_RATIO) of the INI's
    max_accel: Limit  # mm/s²
    max_jerk: Limit | None  # mm/s³; None where not given or 0 (LinuxCNC's default: none)


@dataclass(frozen=True)
class MachineLimits:
    """What a LinuxCNC INI file says of the machine's limits, in mm and s."""

    source: str
    mm_per_unit: float
    axes: tuple  # (AxisLimits, ...) of the axes the file describes, in X, Y, Z order
    max_linear_velocity: Limit | None  # mm/s, [TRAJ] MAX_LINEAR_VELOCITY
    servo_period: Limit | None  # s, [EMCMOT] SERVO_PERIOD


def read_ini(path: str | os.PathLike) -> dict[str, dict[str, Entry]]:
    """The file's sections: ``{section: {name: Entry}}``, the first of a name kept (LinuxCNC's rule)."""
    sections: dict[str, dict[str, Entry]] = {}
    _read_into(os.fspath(path), sections, [], {"section": None})
    return sections


def _read_into(name: str, sections: dict, stack: list, state: dict) -> None:
    """Read file *name* into *sections*; *state* holds the section in effect, which runs on into and out of an
    included file as in LinuxCNC's reader (one parser reads the lines of all the files in order)."""
    if os.path.isdir(name):
        raise SpecError(f"{name}: is a directory, not a LinuxCNC INI file")
    try:
        with open(name, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise SpecError(f"{name}: cannot read: {exc.strerror or exc}") from None
    # a comment in Latin-1 is common in old files and harmless; a value that is not a number is refused anyway
    text = data.decode("utf-8", errors="replace")
    stack = [*stack, os.path.abspath(name)]
    for number, line in _logical_lines(name, text):
        if line.startswith("#INCLUDE"):
            target = line[len("#INCLUDE"):].strip()
            if not target or line[len("#INCLUDE")] not in " \t":
                raise SpecError(f"{name}:{number}: #INCLUDE names no file")
            target = os.path.expanduser(target)
            if not os.path.isabs(target):
                target = os.path.join(os.path.dirname(name), target)
            if os.path.abspath(target) in stack:
                raise SpecError(f"{name}:{number}: #INCLUDE {target}: includes itself (through {len(stack)} files)")
            if len(stack) >= MAX_INCLUDE_DEPTH:
                raise SpecError(f"{name}:{number}: #INCLUDE {target}: more than {MAX_INCLUDE_DEPTH} files deep")
            _read_into(target, sections, stack, state)
            continue
        text_ = line.strip()
        if not text_ or text_[0] in "#;":
            continue
        if text_[0] == "[":
            end = text_.find("]")
            if end < 0:
                raise SpecError(f"{name}:{number}: section header {text_!r} has no ']'")
            state["section"] = text_[1:end].strip()
            if not state["section"]:
                raise SpecError(f"{name}:{number}: section header {text_!r} names no section")
            sections.setdefault(state["section"], {})
            continue
        key, eq, value = text_.partition("=")
        key = key.strip()
        if not eq:
            raise SpecError(f"{name}:{number}: {text_!r} is not NAME = VALUE")
        if not key:
            raise SpecError(f"{name}:{number}: {text_!r} has no name before '='")
        section = state["section"]
        if section is None:
            raise SpecError(f"{name}:{number}: {key} is given before any [SECTION]")
        # the first of a name wins: a later one is LinuxCNC's "commented out carelessly" case
        sections[section].setdefault(key, Entry(section, key, value.strip(), name, number))


def _logical_lines(name: str, text: str):
    """(number of the first physical line, the line) with continuations (a trailing backslash) joined."""
    pending, first = "", 0
    lines = text.split("\n")
    if lines and lines[-1] == "":  # the final newline ends the last line, it does not open another
        lines.pop()
    for i, raw in enumerate(lines, start=1):
        line = raw.rstrip()  # also a CR of CRLF, and blanks after a continuation's backslash, as LinuxCNC
        if not pending:
            first = i
        if line.endswith("\\"):
            pending += line[:-1]
            if i == len(lines):
                raise SpecError(f"{name}:{i}: the last line ends in a continuation '\\'")
            continue
        yield first, pending + line
        pending = ""


def _number(entry: Entry) -> float:
    """The entry's value as a finite number (strtod's decimal form, a trailing comment allowed)."""
    m = _NUMBER.match(entry.value)
    if m is None or not _TRAILING_COMMENT.match(entry.value[m.end():]):
        raise SpecError(f"{entry.where} = {entry.value!r} is not a number")
    value = float(m.group(0))
    if not math.isfinite(value):
        raise SpecError(f"{entry.where} = {entry.value!r} is too large")
    return value


def _positive(entry: Entry, zero_means_none: bool = False) -> float | None:
    value = _number(entry)
    if value == 0 and zero_means_none:
        return None
    if not value > 0:
        raise SpecError(f"{entry.where} = {entry.value!r} must be > 0")
    return value


def read_machine(path: str | os.PathLike) -> MachineLimits:
    """The limits of the machine a LinuxCNC INI file describes (see the module's docstring), in mm and s.

    Raises SpecError, one line naming the file, line and variable, for a file that cannot be read, a line that
    is not INI, a value that is not a number or not > 0, a file with no limits of X, Y or Z, and an axis whose
    limits are neither in its [AXIS_L] section nor (trivkins) in its joints'.
    """
    name = os.fspath(path)
    sections = read_ini(name)
    traj = sections.get("TRAJ", {})
    joints = _joints_of_axes(name, sections)
    present = [letter for letter in AXIS_LETTERS if f"AXIS_{letter}" in sections or letter in joints]
    if not present:
        numbered = sorted(s for s in sections if re.fullmatch(r"AXIS_\d", s))
        hint = (f"; [{numbered[0]}] is LinuxCNC 2.7's joint section: LinuxCNC's update_ini converts the file"
                if numbered else "")
        raise SpecError(f"{name}: has no [AXIS_X], [AXIS_Y] or [AXIS_Z] section (MAX_VELOCITY, MAX_ACCELERATION) "
                        f"and no trivkins joints of those axes{hint}")
    mm_per_unit = _linear_units(name, traj.get("LINEAR_UNITS"))
    axes = []
    for letter in present:
        section = sections.get(f"AXIS_{letter}", {})
        ratio = 0.0
        if "OFFSET_AV_RATIO" in section:
            entry = section["OFFSET_AV_RATIO"]
            ratio = _number(entry)
            if not 0.0 <= ratio <= MAX_OFFSET_AV_RATIO:
                raise SpecError(f"{entry.where} = {entry.value!r} must be between 0 and {MAX_OFFSET_AV_RATIO} "
                                "(the share of the limits kept for external offsets)")
        limits = {}
        for key, power in (("MAX_VELOCITY", 1), ("MAX_ACCELERATION", 2)):
            if key in section:
                entry = section[key]
                value, where = _positive(entry), entry.where
            else:
                value, where = _from_joints(name, sections, letter, key, joints)
            # the planner's share: LinuxCNC plans with (1 - ratio) and keeps the rest for external offsets
            scaled = value * mm_per_unit * (1.0 - ratio)
            if not math.isfinite(scaled):
                raise SpecError(f"{where} = {value!r} is too large")
            if ratio:
                where += f" x (1 - OFFSET_AV_RATIO {ratio:g})"
            limits[key] = Limit(scaled, where)
        jerk = None
        if "MAX_JERK" in section:
            entry = section["MAX_JERK"]
            value = _positive(entry, zero_means_none=True)  # LinuxCNC's default 0: no jerk limit
            jerk = None if value is None else Limit(value * mm_per_unit, entry.where)
        axes.append(AxisLimits(letter.lower(), limits["MAX_VELOCITY"], limits["MAX_ACCELERATION"], jerk))
    vmax = None
    if "MAX_LINEAR_VELOCITY" in traj:
        entry = traj["MAX_LINEAR_VELOCITY"]
        vmax = Limit(_positive(entry) * mm_per_unit, entry.where)
    period = None
    emcmot = sections.get("EMCMOT", {})
    if "SERVO_PERIOD" in emcmot:
        entry = emcmot["SERVO_PERIOD"]
        period = Limit(_positive(entry) * 1e-9, entry.where)
    return MachineLimits(name, mm_per_unit, tuple(axes), vmax, period)


def _linear_units(name: str, entry: Entry | None) -> float:
    """mm per machine unit from [TRAJ] LINEAR_UNITS (LinuxCNC will not start without it)."""
    if entry is None:
        raise SpecError(f"{name}: has no [TRAJ] LINEAR_UNITS (mm or inch): the limits' unit is unknown")
    word = entry.value.split()[0].lower() if entry.value.split() else ""
    if word in LINEAR_UNITS and _TRAILING_COMMENT.match(entry.value[len(word):].rstrip() or ""):
        return LINEAR_UNITS[word]
    if _NUMBER.match(entry.value):
        units_per_mm = _number(entry)  # LinuxCNC 2.9: a number is units per mm (1/25.4 for inch)
        if units_per_mm > 0:
            return 1.0 / units_per_mm
        raise SpecError(f"{entry.where} = {entry.value!r} must be > 0 (machine units per mm)")
    raise SpecError(f"{entry.where} = {entry.value!r} is not a unit: give mm, inch, or machine units per mm")


def _joints_of_axes(name: str, sections: dict) -> dict[str, list[int]]:
    """{letter: [joint, ...]} of a trivkins machine (identity kinematics); {} for any other kinematics."""
    kins = sections.get("KINS", {})
    entry = kins.get("KINEMATICS")
    if entry is None or not entry.value.split() or entry.value.split()[0] != "trivkins":
        return {}
    coordinates = TRIVKINS_COORDINATES
    for word in entry.value.split()[1:]:
        key, _, value = word.partition("=")
        if key == "coordinates":
            coordinates = value.upper()
    count = len(coordinates)
    if "JOINTS" in kins:
        joints = kins["JOINTS"]
        n = _number(joints)
        if n != int(n) or n < 1:
            raise SpecError(f"{joints.where} = {joints.value!r} must be a whole number >= 1")
        count = min(count, int(n))
    out: dict[str, list[int]] = {}
    for j, letter in enumerate(coordinates[:count]):
        out.setdefault(letter, []).append(j)
    return out


def _from_joints(name: str, sections: dict, letter: str, key: str, joints: dict) -> tuple[float, str]:
    """The lowest *key* of the trivkins joints of axis *letter*, and where it was read."""
    if letter not in joints:
        kins = sections.get("KINS", {}).get("KINEMATICS")
        why = ("[KINS] KINEMATICS is not given" if kins is None else
               f"{kins.where} = {kins.value!r} is not trivkins, whose joints would be its axes")
        raise SpecError(f"{name}: [AXIS_{letter}] has no {key} (LinuxCNC would use 1 unit/s), and {why}: "
                        f"give [AXIS_{letter}] {key}")
    found = []
    for j in joints[letter]:
        entry = sections.get(f"JOINT_{j}", {}).get(key)
        if entry is None:
            raise SpecError(f"{name}: neither [AXIS_{letter}] nor [JOINT_{j}] (trivkins' joint of {letter}) "
                            f"gives {key}")
        found.append((_positive(entry), entry.where))
    return min(found)
