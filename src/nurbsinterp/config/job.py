"""The job: geometry (a curve or a path), feedrate profile and interpolator, validated and frozen."""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from typing import Any

from ..errors import SpecError
from ..names import ACCDEC, METHODS, PROFILE_TYPES
from .curve import CURVE_KEYS, CurveSpec, validate_curve
from .path import PATH_KEYS, PathSpec, path_of_curve, validate_path
from .reading import read_yaml
from .rules import Where, choice, mapping, quantity
from .units import show

LIMIT_FIELDS = {  # the adaptive profile's limits: field -> kind of quantity
    "chord_tolerance": "length",
    "max_accel": "accel",
    "max_jerk": "jerk",
    "max_normal_accel": "accel",
    "corner_tolerance": "length",
}
AXIS_LIMITS = {"max_velocity": "feedrate", "max_accel": "accel", "max_jerk": "jerk"}
SECTION_KEYS = {
    "curve": CURVE_KEYS,
    "path": PATH_KEYS,
    "profile": ("type", "feedrate", "accel_time", "time_constant", "accdec", *LIMIT_FIELDS, "axes",
                "rapid_feedrate"),
    "interpolator": ("method", "period"),
}

RAPID_FEEDRATE = 10_000.0 / 60.0  # mm/s


@dataclass(frozen=True)
class ProfileSpec:
    """Feedrate planning.  feedrate in mm/s, accel_time and time_constant in s."""

    type: str = "trapezoidal"
    feedrate: float = 100.0
    accel_time: float = 0.5
    time_constant: float | None = None  # exponential only; None means accel_time / 4
    accdec: str = "before"
    # the adaptive type's limits (None: no such limit); the other types ignore them
    chord_tolerance: float | None = None  # mm
    max_accel: float | None = None  # mm/s², tangential
    max_jerk: float | None = None  # mm/s³, tangential
    max_normal_accel: float | None = None  # mm/s², centripetal
    corner_tolerance: float | None = None  # mm a corner blend may leave the path by (None: corners are stops)
    axes: tuple = ()  # ((axis, max_velocity or None, max_accel or None), ...)
    # the feedrate of rapid (G0) blocks, mm/s: 10 000 mm/min, a small mill's rapid; set the machine's own
    rapid_feedrate: float = RAPID_FEEDRATE

    @property
    def tau(self) -> float:
        """Time constant of the exponential shape and of the after-interpolation lag."""
        return self.time_constant if self.time_constant is not None else self.accel_time / 4.0


@dataclass(frozen=True)
class InterpolatorSpec:
    """The real-time interpolator: method and sampling period T in s.

    ``method_default`` is True where the job left the method to the default: ``taylor2``
    (the paper's Eq. 9), or ``exact`` with the adaptive profile, whose limits only an
    interpolator that follows the plan exactly keeps in the emitted stream (the Taylor
    and RK methods drift from the plan by their truncation error and snap at the end).
    """

    method: str = "taylor2"
    period: float = 0.001
    method_default: bool = field(default=False, compare=False)  # provenance, not part of the value


@dataclass(frozen=True)
class Job:
    path: PathSpec
    profile: ProfileSpec = field(default_factory=ProfileSpec)
    interpolator: InterpolatorSpec = field(default_factory=InterpolatorSpec)
    source: str = "<job>"
    # how the user wrote the fields a summary echoes: ((dotted field, value as written, where from), ...)
    given: tuple = ()
    # profile.feedrate was set by an override (the command line): it wins over the blocks' own feedrates
    feedrate_override: bool = False
    # the profile was chosen (its type or accel_time given: the job, a profile file, the command line): its ramp
    # binds the look-ahead even on a machine with limits of its own (motion.limits.motion_limits)
    profile_chosen: bool = False
    # profile.accel_time was stated with the profile type in effect (the same file, or on the command line): the
    # adaptive profile's own ramp then; a job file's accel_time under --profile-type adaptive is not (it was written
    # for the file's own profile, and is noted unused where the paper's planner plans)
    accel_time_stated: bool = False
    # what loading has to tell that is not an error (fields the profile does not use, from a file whose
    # profile type was replaced): said once on stderr
    notes: tuple = field(default=(), compare=False)

    def with_overrides(self, **changes) -> "Job":
        return replace(self, **changes)

    @property
    def curve(self) -> CurveSpec:
        """The job's one NURBS curve (a `curve:` job, or a path of one nurbs block); ValueError otherwise."""
        return self.path.curve


def validate_profile(raw: dict, where: Where) -> ProfileSpec:
    raw = mapping(where, "profile", raw, SECTION_KEYS["profile"])
    kwargs: dict[str, Any] = {}
    if "type" in raw:
        kwargs["type"] = choice(where, "profile.type", raw["type"], PROFILE_TYPES)
    for key in ("feedrate", "rapid_feedrate"):
        if key in raw:
            kwargs[key] = quantity(where, f"profile.{key}", raw[key], "feedrate")
    if "accel_time" in raw:
        kwargs["accel_time"] = quantity(where, "profile.accel_time", raw["accel_time"], "time", zero_ok=True)
    if "time_constant" in raw and raw["time_constant"] is not None:
        kwargs["time_constant"] = quantity(where, "profile.time_constant", raw["time_constant"], "time")
    if "accdec" in raw:
        kwargs["accdec"] = choice(where, "profile.accdec", raw["accdec"], ACCDEC)
    for key, kind in LIMIT_FIELDS.items():
        if raw.get(key) is not None:
            kwargs[key] = quantity(where, f"profile.{key}", raw[key], kind)
    if raw.get("axes") is not None:
        axes_raw = mapping(where, "profile.axes", raw["axes"], ("x", "y", "z"))
        axes = []
        for axis in ("x", "y", "z"):
            if axis not in axes_raw:
                continue
            limits = mapping(where, f"profile.axes.{axis}", axes_raw[axis], tuple(AXIS_LIMITS))
            axes.append((axis, *(None if limits.get(key) is None else
                                 quantity(where, f"profile.axes.{axis}.{key}", limits[key], kind)
                                 for key, kind in AXIS_LIMITS.items())))
        kwargs["axes"] = tuple(axes)
    spec = ProfileSpec(**kwargs)
    if spec.type == "adaptive" and spec.accdec == "after":
        raise where.fail("profile.accdec", "after", "cannot be used with profile.type = 'adaptive', "
                         "which plans the feedrate along the curve before interpolation")
    _check_ramp(spec, where)
    return spec


def _check_ramp(spec: ProfileSpec, where: Where) -> None:
    """The ramp's acceleration must be a number: a subnormal accel_time or time constant makes it inf.

    The bound is the largest acceleration any shape reaches before the peak is
    lowered: F/Ta·π/2 (bell), F/τ (exponential, whose ratio Ta/τ must also be finite).
    """
    if spec.accel_time == 0:
        return
    F, Ta, tau = spec.feedrate, spec.accel_time, spec.tau
    problem = (f"s is too short: profile.feedrate = {F:g} mm/s would be reached with an infinite acceleration "
               "(accel_time 0 gives an instant start)")
    if not math.isfinite(F / Ta * math.pi / 2):
        raise where.fail("profile.accel_time", Ta, problem)
    if spec.type == "exponential":
        fieldname, value = (("profile.time_constant", spec.time_constant) if spec.time_constant is not None
                            else ("profile.accel_time", Ta))
        if not (tau > 0 and math.isfinite(F / tau) and math.isfinite(Ta / tau)):
            raise where.fail(fieldname, value, problem)


def validate_interpolator(raw: dict, where: Where) -> InterpolatorSpec:
    raw = mapping(where, "interpolator", raw, SECTION_KEYS["interpolator"])
    kwargs: dict[str, Any] = {}
    if "method" in raw:
        kwargs["method"] = choice(where, "interpolator.method", raw["method"], METHODS)
    if "period" in raw:
        kwargs["period"] = quantity(where, "interpolator.period", raw["period"], "time")
    return InterpolatorSpec(**kwargs)


def _adaptive(profile: ProfileSpec) -> bool:
    return profile.type == "adaptive"


#: the fields some profiles ignore: field -> (does *profile* use it?, the profiles that do).  A field
#: given for a profile that ignores it is refused or noted (see :func:`unused_fields`); a new
#: field that only some profiles read is added here.
USED_BY = {
    **{f"profile.{key}": (_adaptive, "the adaptive profile") for key in (*LIMIT_FIELDS, "axes")},
    "profile.time_constant": (lambda p: p.type == "exponential", "the exponential profile"),
    # the adaptive profile reads accel_time only as its max_accel's stand-in, feedrate / accel_time
    "profile.accel_time": (lambda p: not _adaptive(p) or p.max_accel is None,
                           "the trapezoidal, exponential and bell profiles (the adaptive one without max_accel)"),
}


def unused_fields(profile: ProfileSpec, sections: dict, origins: dict[str, str], name: str,
                  overridden: set[str]) -> tuple[str, ...]:
    """Refuse the fields the planned *profile* ignores, or note them (the notes are returned).

    Refused (SpecError, one line naming each field, its value and the profile): a field given
    on the command line (*overridden*), or in the same file as the profile type in effect (the
    job file when no file states one) -- a field that file's own profile never reads.  Noted: a
    field from a file whose profile type another file or the command line replaced (a job
    written for the bell profile planned with the adaptive one), or from a shared profile file
    that states no type (a machine's limits used with every profile).

    *sections* are the raw profile and interpolator sections, *origins* where each field that
    did not come from the job file *name* came from.
    """
    type_origin = origins.get("profile.type", name)
    chosen = (f"the {profile.type} profile " + (f"chosen by {type_origin}" if "profile.type" in overridden else
              f"of {type_origin}" if "type" in sections["profile"] else "(the default profile.type)"))
    refused: dict[str, list[str]] = {}  # the profiles that read them -> the fields, as the user gave them
    noted: dict[str, list[str]] = {}  # the file -> its fields
    for dotted, (uses, users) in USED_BY.items():
        section, key = dotted.split(".")
        raw = sections[section].get(key)
        if raw is None or raw == {} or uses(profile):
            continue
        origin = origins.get(dotted, name)
        per_axis = sorted(k for k in overridden if k.startswith(dotted + "."))  # profile.axes.x.max_velocity
        if dotted in overridden:
            refused.setdefault(users, []).append(f"{origin} {raw}")
        elif per_axis:  # an axis option: named as the user gave it, axis by axis
            for key in per_axis:
                _, _, axis, limit = key.split(".")
                refused.setdefault(users, []).append(f"{origins[key]} {axis}={raw[axis][limit]}")
        elif origin == type_origin:
            refused.setdefault(users, []).append(f"{origin}: {dotted} = {show(raw)}")
        else:
            noted.setdefault(origin, []).append(f"{dotted} = {show(raw)}")
    if refused:
        # "refused", not "ignored": the run stops here, and the line must not read as a warning it went past
        raise SpecError("; ".join(f"{', '.join(fields)} {_is(fields)} refused: {chosen} does not read {_it(fields)}, "
                                  f"only {users} read{'s' if ' profiles' not in users else ''} {_it(fields)}"
                                  for users, fields in refused.items()))
    return tuple(f"{origin}: {', '.join(fields)} {_is(fields)} not used: {chosen} ignores {_it(fields)}"
                 for origin, fields in noted.items())


def _is(items) -> str:
    return "is" if len(items) == 1 else "are"


def _it(items) -> str:
    return "it" if len(items) == 1 else "them"


def load_job(path: str | os.PathLike, *, profile_file: str | os.PathLike | None = None,
             overrides: dict[str, tuple[Any, str]] | None = None, input_format: str | None = None,
             reader_options: dict[str, Any] | None = None, every_profile: bool = False, stream: bool = False) -> Job:
    """Read and validate a job.

    Parameters
    ----------
    path : the job: YAML with ``curve`` or ``path``, optional ``profile`` and
        ``interpolator``; or any format a registered reader takes (:mod:`.readers`,
        chosen by the file's suffix or *input_format*).
    profile_file : optional YAML with ``profile`` and/or ``interpolator`` sections; its
        fields override the job file's, field by field.
    overrides : ``{dotted field: (value, origin)}``, e.g. ``{"profile.feedrate":
        ("6000 mm/min", "--feedrate")}`` or ``{"profile.axes.x.max_accel": ("800", "--axis-max-accel")}``;
        the origin names where the value came from in messages.  ``None`` values are ignored.  They win over both files.
    input_format : the reader to use whatever the suffix (``yaml``, ``gcode``, ``dxf``).
    reader_options : the reader's own settings (see :mod:`.readers`), None values ignored.
    every_profile : the caller plans the job with every profile type (a comparison), so no
        field goes unused; otherwise a field the job's profile ignores is refused or noted
        (:func:`unused_fields`).
    stream : the job's path as the format's streaming reader gives it, where it has one (a G-code program:
        ``config.gcode.ProgramStream``, its blocks read as they are planned), else held whole.
    """
    from .readers import reader_for

    name = os.fspath(path)
    options = {key: value for key, value in (reader_options or {}).items() if value is not None}
    geometry, sections = reader_for(name, input_format, stream)(name, **options)
    sections = {s: dict(sections.get(s) or {}) for s in ("profile", "interpolator")}
    origins: dict[str, str] = {}
    if profile_file is not None:
        pname = os.fspath(profile_file)
        pdoc = read_yaml(pname)
        pwhere = Where(pname)
        mapping(pwhere, "", pdoc, ("profile", "interpolator"))
        for section in ("profile", "interpolator"):
            if section in pdoc:
                for key, value in mapping(pwhere, section, pdoc[section], SECTION_KEYS[section]).items():
                    sections[section][key] = value
                    origins[f"{section}.{key}"] = pname
    for dotted, (value, origin) in (overrides or {}).items():
        if value is None:
            continue
        section, key, *axis = dotted.split(".")
        if axis:  # profile.axes.x.max_accel: one limit of one axis, over the file's own limits of it
            _set_axis_limit(sections[section], key, *axis, value)
        else:
            sections[section][key] = value
        origins[dotted] = origin
    where = Where(name, origins)
    given = tuple((dotted, sections[dotted.split(".")[0]][dotted.split(".")[1]], origins.get(dotted, name))
                  for dotted in ECHOED_FIELDS if dotted.split(".")[1] in sections[dotted.split(".")[0]])
    profile = validate_profile(sections["profile"], where)
    interpolator = validate_interpolator(sections["interpolator"], where)
    if "method" not in sections["interpolator"]:
        interpolator = replace(interpolator, method="exact" if profile.type == "adaptive" else "taylor2",
                               method_default=True)
    overridden = {dotted for dotted, (value, _origin) in (overrides or {}).items() if value is not None}
    notes = () if every_profile else unused_fields(profile, sections, origins, name, overridden)
    stated = "accel_time" in sections["profile"] and (
        "profile.accel_time" in overridden
        or origins.get("profile.accel_time", name) == origins.get("profile.type", name))
    return Job(path=geometry, profile=profile, interpolator=interpolator, source=name, given=given,
               feedrate_override="profile.feedrate" in overridden,
               profile_chosen=bool({"type", "accel_time"} & set(sections["profile"])), accel_time_stated=stated,
               notes=notes)


def _set_axis_limit(section: dict, key: str, axis: str, limit: str, value) -> None:
    """section[key][axis][limit] = value on copies (the file's mapping is not changed); a malformed
    section[key] is left for validate_profile to name."""
    axes = section.get(key)
    axes = {} if axes is None else axes
    if not isinstance(axes, dict):
        return
    entry = axes.get(axis)
    entry = {} if entry is None else entry
    if isinstance(entry, dict):
        section[key] = {**axes, axis: {**entry, limit: value}}


def read_yaml_job(name: str, **_options):
    """The YAML reader: (the path, the raw profile and interpolator sections); it has no options."""
    doc = read_yaml(name)
    where = Where(name)
    mapping(where, "", doc, tuple(SECTION_KEYS))
    if ("curve" in doc) == ("path" in doc):
        raise SpecError(f"{name}: has no 'curve' or 'path' section" if "curve" not in doc
                        else f"{name}: has both a 'curve' and a 'path' section; give one")
    geometry = (path_of_curve(validate_curve(doc["curve"], where)) if "curve" in doc
                else validate_path(doc["path"], where))
    sections = {s: mapping(where, s, {} if doc.get(s) is None else doc[s], SECTION_KEYS[s])
                for s in ("profile", "interpolator")}
    return geometry, sections


#: the fields whose units a run summary echoes, so that a user can confirm a conversion
ECHOED_FIELDS = ("profile.feedrate", "profile.accel_time", "interpolator.period")
