"""Validation of job files: every violated rule is one SpecError naming file, field, index, value.

The table below mutates a valid job (the paper's circle) one rule at a time, writes it as
YAML into tmp_path and checks the message of :func:`nurbsinterp.config.load_job`.
"""
from __future__ import annotations

import copy
import math
import re

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from budgets import budgets

from nurbsinterp import NurbsCurve
from nurbsinterp.errors import NurbsInterpError, SpecError
from nurbsinterp.config import InterpolatorSpec, Job, ProfileSpec, load_job, parse_quantity, read_yaml
from nurbsinterp.config.reading import FAST_YAML_BYTES, _fast_yaml, _Loader, _Unusual
from nurbsinterp.cli.common import load_cli

CIRCLE_POINTS = [[0, 0], [0, 50], [100, 50], [100, 0], [100, -50], [0, -50], [0, 0]]
CIRCLE_WEIGHTS = [1, 0.5, 0.5, 1, 0.5, 0.5, 1]
CIRCLE_KNOTS = [0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1]
CIRCLE = {
    "curve": {
        "degree": 2,
        "control_points": CIRCLE_POINTS,
        "weights": CIRCLE_WEIGHTS,
        "knots": CIRCLE_KNOTS,
    },
    "profile": {"type": "trapezoidal", "feedrate": "100 mm/s", "accel_time": "0.5 s"},
    "interpolator": {"method": "taylor2", "period": "1 ms"},
}
NAN = float("nan")
INF = float("inf")


# --------------------------------------------------------------------------- helpers


def circle() -> dict:
    return copy.deepcopy(CIRCLE)


_STEP = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def _walk(doc, dotted):
    """('curve.knots[4]') -> (container, final key or index)."""
    steps = [name if name else int(index) for name, index in _STEP.findall(dotted)]
    for step in steps[:-1]:
        doc = doc[step]
    return doc, steps[-1]


def SET(dotted, value):
    def apply(doc):
        box, key = _walk(doc, dotted)
        box[key] = copy.deepcopy(value)
    return apply


def DEL(dotted):
    def apply(doc):
        box, key = _walk(doc, dotted)
        del box[key]
    return apply


def write_doc(tmp_path, doc, name="job.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


def write_text(tmp_path, text, name="job.yaml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def spec_error(path, **kwargs) -> str:
    """Load *path*, expect a SpecError, check the one-line contract and return the message."""
    with pytest.raises(SpecError) as info:
        load_job(path, **kwargs)
    return check_message(info.value)


def check_message(exc: BaseException) -> str:
    assert isinstance(exc, SpecError)
    assert isinstance(exc, ValueError) and isinstance(exc, NurbsInterpError)
    message = str(exc)
    assert message.strip() == message and message, repr(message)
    assert "\n" not in message and "\r" not in message, f"message spans several lines: {message!r}"
    assert "Traceback" not in message
    return message


def assert_names(message: str, source, *parts: str) -> None:
    assert message.startswith(f"{source}: "), f"message does not start with the source {source}: {message!r}"
    for part in parts:
        assert part in message, f"{part!r} not in {message!r}"


# --------------------------------------------------------------------------- the rule table

# (id, mutations, expected substrings of the message after "job.yaml: ")
RULES = [
    # ---- degree / order
    ("degree-missing", [DEL("curve.degree")], ["curve needs a degree", "order"]),
    ("degree-and-order", [SET("curve.order", 3)], ["curve.order = 3", "curve.degree"]),
    ("degree-zero", [SET("curve.degree", 0)], ["curve.degree = 0 must be >= 1"]),
    ("degree-negative", [SET("curve.degree", -2)], ["curve.degree = -2 must be >= 1"]),
    ("degree-non-integer", [SET("curve.degree", 2.5)], ["curve.degree = 2.5 must be an integer"]),
    ("degree-string", [SET("curve.degree", "two")], ["curve.degree = 'two' must be an integer"]),
    ("degree-bool", [SET("curve.degree", True)], ["curve.degree = true must be an integer"]),
    ("degree-null", [SET("curve.degree", None)], ["curve.degree = null must be an integer"]),
    ("degree-nan", [SET("curve.degree", NAN)], ["curve.degree = nan must be an integer"]),
    ("degree-inf", [SET("curve.degree", INF)], ["curve.degree = inf must be an integer"]),
    ("degree-list", [SET("curve.degree", [2])], ["curve.degree = [2] must be an integer"]),
    ("degree-26", [SET("curve.degree", 26)], ["curve.degree = 26 is above the supported maximum of 25"]),
    ("degree-huge", [SET("curve.degree", 10**12)],
     ["curve.degree = 1000000000000 is above the supported maximum of 25"]),
    ("order-1", [DEL("curve.degree"), SET("curve.order", 1)], ["curve.order = 1 must be >= 2"]),
    ("order-0", [DEL("curve.degree"), SET("curve.order", 0)], ["curve.order = 0 must be >= 2"]),
    ("order-27", [DEL("curve.degree"), SET("curve.order", 27)],
     ["curve.order = 27 is above the supported maximum of 26"]),
    ("order-non-integer", [DEL("curve.degree"), SET("curve.order", 3.5)], ["curve.order = 3.5 must be an integer"]),
    ("order-bool", [DEL("curve.degree"), SET("curve.order", False)], ["curve.order = false must be an integer"]),
    # ---- control points
    ("cps-missing", [DEL("curve.control_points")], ["curve needs control_points"]),
    ("cps-empty", [SET("curve.control_points", [])], ["curve.control_points = [] must be a non-empty list"]),
    ("cps-string", [SET("curve.control_points", "circle")],
     ["curve.control_points = 'circle' must be a non-empty list"]),
    ("cps-mapping", [SET("curve.control_points", {"x": 1})], ["curve.control_points = {'x': 1} must be a non-empty list"]),
    ("cps-null", [SET("curve.control_points", None)], ["curve.control_points = null must be a non-empty list"]),
    ("cp-1-coordinate", [SET("curve.control_points[3]", [100])],
     ["curve.control_points[3] = [100] must be a point [x, y] or [x, y, z]"]),
    ("cp-4-coordinates", [SET("curve.control_points[3]", [100, 0, 0, 0])],
     ["curve.control_points[3] = [100, 0, 0, 0] must be a point"]),
    ("cp-0-coordinates", [SET("curve.control_points[3]", [])], ["curve.control_points[3] = [] must be a point"]),
    ("cp-beyond-1e12", [SET("curve.control_points[2]", [100, 1.5e12])],
     ["curve.control_points[2][1] = 1500000000000.0 mm is beyond the supported range of +-1e+12 mm"]),
    ("cp-at-1e12", [SET("curve.control_points[2]", [100, -1e12])], None),
    # ---- scale rules that keep u resolvable and the derivatives finite
    ("weights-ratio-1e7", [SET("curve.weights", [1, 0.5, 0.5, 1, 0.5, 5e6, 1])],
     ["curve.weights[5] = 5000000.0 is 1e+07 times curve.weights[1] = 0.5", "at most 1e+06"]),
    ("weights-ratio-1e6", [SET("curve.weights", [1, 0.5, 0.5, 1, 0.5, 5e5, 1])], None),
    ("knots-beyond-1e30", [SET("curve.knots", [0, 0, 0, 0.25, 0.5, 0.5, 0.75, 2e30, 2e30, 2e30])],
     ["curve.knots domain [0, 2e+30] is beyond +-1e+30"]),
    ("knot-span-1e-31", [SET("curve.knots", [0, 0, 0, 1e-31, 0.5, 0.5, 0.75, 1, 1, 1])],
     ["curve.knots domain [0, 1] has a knot span of 1e-31, narrower than 1e-30"]),
    ("knots-few-ulps-wide", [SET("curve.knots", [1, 1, 1, 1 + 2e-16, 1 + 4e-16, 1 + 4e-16, 1 + 6e-16, 1 + 8e-16,
                                                 1 + 8e-16, 1 + 8e-16])],
     ["curve.knots domain [1.0, 1.0000000000000009] is too narrow for its magnitude", "mm apart on the curve"]),
    ("knots-1e-20-wide-near-0", [SET("curve.knots", [0, 0, 0, 2.5e-21, 5e-21, 5e-21, 7.5e-21, 1e-20, 1e-20, 1e-20])],
     None),
    ("cp-scalar", [SET("curve.control_points[3]", 100)], ["curve.control_points[3] = 100 must be a point"]),
    ("cp-mixed-2d-3d", [SET("curve.control_points[2]", [100, 50, 0])],
     ["curve.control_points[2] = [100, 50, 0] has 3 coordinates; curve.control_points[0] has 2"]),
    ("cp-mixed-3d-2d", [SET("curve.control_points", [[0, 0, 0], [0, 50, 0], [100, 50], [100, 0, 0],
                                                     [100, -50, 0], [0, -50, 0], [0, 0, 0]])],
     ["curve.control_points[2] = [100, 50] has 2 coordinates; curve.control_points[0] has 3"]),
    ("cp-non-numeric", [SET("curve.control_points[2][1]", "fifty")],
     ["curve.control_points[2][1] = 'fifty' is not a number"]),
    ("cp-null", [SET("curve.control_points[5][0]", None)], ["curve.control_points[5][0] = null is not a number"]),
    ("cp-bool", [SET("curve.control_points[1][0]", True)], ["curve.control_points[1][0] = true is not a number"]),
    ("cp-nan", [SET("curve.control_points[2][0]", NAN)], ["curve.control_points[2][0] = nan must be a finite number"]),
    ("cp-inf", [SET("curve.control_points[4][1]", INF)], ["curve.control_points[4][1] = inf must be a finite number"]),
    ("cp-minus-inf", [SET("curve.control_points[4][1]", -INF)],
     ["curve.control_points[4][1] = -inf must be a finite number"]),
    ("cps-too-few", [SET("curve.control_points", [[0, 0], [0, 50]]), DEL("curve.weights"), DEL("curve.knots")],
     ["curve.control_points", "too few for degree 2", "degree + 1 = 3"]),
    ("cps-too-few-with-weights", [SET("curve.control_points", [[0, 0], [0, 50]])],
     ["curve.control_points", "2 points", "too few for degree 2"]),
    ("cps-too-few-order", [DEL("curve.degree"), SET("curve.order", 9), DEL("curve.knots")],
     ["curve.control_points", "7 points", "too few for degree 8", "degree + 1 = 9"]),
    # ---- weights
    ("weights-too-few", [SET("curve.weights", [1, 0.5, 0.5, 1])],
     ["curve.weights", "4 values", "one weight per control point (7)"]),
    ("weights-too-many", [SET("curve.weights", CIRCLE_WEIGHTS + [1])],
     ["curve.weights", "8 values", "one weight per control point (7)"]),
    ("weights-empty", [SET("curve.weights", [])], ["curve.weights = [] must not be empty"]),
    ("weights-not-list", [SET("curve.weights", "1 .5 .5 1 .5 .5 1")],
     ["curve.weights = '1 .5 .5 1 .5 .5 1' must be a list of numbers"]),
    ("weights-null", [SET("curve.weights", None)], ["curve.weights = null must be a list of numbers"]),
    ("weight-zero", [SET("curve.weights[2]", 0)], ["curve.weights[2] = 0 must be > 0"]),
    ("weight-negative", [SET("curve.weights[2]", -0.5)], ["curve.weights[2] = -0.5 must be > 0"]),
    ("weight-minus-zero", [SET("curve.weights[6]", -0.0)], ["curve.weights[6] = -0.0 must be > 0"]),
    ("weight-nan", [SET("curve.weights[1]", NAN)], ["curve.weights[1] = nan must be a finite number"]),
    ("weight-inf", [SET("curve.weights[1]", INF)], ["curve.weights[1] = inf must be a finite number"]),
    ("weight-string", [SET("curve.weights[3]", "heavy")], ["curve.weights[3] = 'heavy' is not a number"]),
    ("weight-bool", [SET("curve.weights[3]", True)], ["curve.weights[3] = true is not a number"]),
    # ---- knots
    ("knots-too-short", [SET("curve.knots", CIRCLE_KNOTS[:-1])],
     ["curve.knots", "9 values", "wrong length", "need 10 knots"]),
    ("knots-too-long", [SET("curve.knots", CIRCLE_KNOTS + [1])],
     ["curve.knots", "11 values", "wrong length", "need 10 knots"]),
    ("knots-empty", [SET("curve.knots", [])], ["curve.knots = [] must not be empty"]),
    ("knots-not-list", [SET("curve.knots", "uniform")], ["curve.knots = 'uniform' must be a list of numbers"]),
    ("knots-decreasing", [SET("curve.knots", [0, 0, 0, 0.5, 0.3, 0.5, 0.75, 1, 1, 1])],
     ["curve.knots[4] = 0.3 is smaller than curve.knots[3] = 0.5"]),
    ("knots-decreasing-end", [SET("curve.knots", [0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 0.9])],
     ["curve.knots[9] = 0.9 is smaller than curve.knots[8] = 1"]),
    ("knots-unclamped-start", [SET("curve.knots", [0, 0, 0.1, 0.25, 0.5, 0.5, 0.75, 1, 1, 1])],
     ["curve.knots[2] = 0.1 differs from curve.knots[0] = 0", "clamped"]),
    ("knots-unclamped-end", [SET("curve.knots", [0, 0, 0, 0.25, 0.5, 0.5, 0.75, 0.9, 1, 1])],
     ["curve.knots[7] = 0.9 differs from curve.knots[9] = 1", "clamped"]),
    ("knots-start-multiplicity", [SET("curve.knots", [0, 0, 0, 0, 0.5, 0.5, 0.75, 1, 1, 1])],
     ["curve.knots[3] = 0 repeats the start knot", "at most degree + 1 = 3"]),
    ("knots-end-multiplicity", [SET("curve.knots", [0, 0, 0, 0.25, 0.5, 0.5, 1, 1, 1, 1])],
     ["curve.knots[6] = 1 repeats the end knot", "at most degree + 1 = 3"]),
    ("knots-interior-multiplicity", [SET("curve.knots", [0, 0, 0, 0.5, 0.5, 0.5, 0.75, 1, 1, 1])],
     ["curve.knots[5] = 0.5 makes an interior knot of multiplicity 3, more than the degree 2"]),
    ("knots-non-numeric", [SET("curve.knots[3]", "quarter")], ["curve.knots[3] = 'quarter' is not a number"]),
    ("knots-null", [SET("curve.knots[3]", None)], ["curve.knots[3] = null is not a number"]),
    ("knots-inf", [SET("curve.knots[9]", INF)], ["curve.knots[9] = inf must be a finite number"]),
    ("knots-nan", [SET("curve.knots[4]", NAN)], ["curve.knots[4] = nan must be a finite number"]),
    # ---- sections and unknown keys
    ("curve-missing", [DEL("curve")], ["has no 'curve' or 'path' section"]),
    ("curve-null", [SET("curve", None)], ["curve = null must be a mapping with keys degree, order, control_points"]),
    ("curve-list", [SET("curve", [1, 2])], ["curve = [1, 2] must be a mapping"]),
    ("profile-list", [SET("profile", [1])], ["profile = [1] must be a mapping with keys type, feedrate"]),
    ("interpolator-string", [SET("interpolator", "rk4")], ["interpolator = 'rk4' must be a mapping with keys method, period"]),
    ("unknown-top-key", [SET("feed", 100)], ["feed is not a known key", "curve, path, profile, interpolator"]),
    ("unknown-top-key-case", [SET("Curve", {})], ["Curve is not a known key"]),
    ("unknown-curve-key", [SET("curve.colour", "red")], ["curve.colour is not a known key", "degree, order, control_points"]),
    ("unknown-curve-key-typo", [SET("curve.knot", CIRCLE_KNOTS)], ["curve.knot is not a known key"]),
    ("unknown-profile-key", [SET("profile.speed", 5)], ["profile.speed is not a known key", "type, feedrate, accel_time"]),
    ("unknown-interpolator-key", [SET("interpolator.dt", 0.001)],
     ["interpolator.dt is not a known key", "method, period"]),
    # ---- choices
    ("profile-type", [SET("profile.type", "scurve")],
     ["profile.type = 'scurve' is not one of trapezoidal, exponential, bell"]),
    ("profile-type-case", [SET("profile.type", "Bell")], ["profile.type = 'Bell' is not one of"]),
    ("profile-type-number", [SET("profile.type", 1)], ["profile.type = 1 is not one of"]),
    ("profile-accdec", [SET("profile.accdec", "during")], ["profile.accdec = 'during' is not one of before, after"]),
    ("interpolator-method", [SET("interpolator.method", "euler")],
     ["interpolator.method = 'euler' is not one of taylor1, taylor2, rk4, exact"]),
    ("interpolator-method-null", [SET("interpolator.method", None)], ["interpolator.method = null is not one of"]),
    # ---- feedrate
    ("feedrate-negative", [SET("profile.feedrate", -100)], ["profile.feedrate = -100 must be > 0"]),
    ("feedrate-negative-unit", [SET("profile.feedrate", "-100 mm/s")], ["profile.feedrate = '-100 mm/s' must be > 0"]),
    ("feedrate-zero", [SET("profile.feedrate", 0)], ["profile.feedrate = 0 must be > 0"]),
    ("feedrate-zero-unit", [SET("profile.feedrate", "0 mm/min")], ["profile.feedrate = '0 mm/min' must be > 0"]),
    ("feedrate-unknown-unit", [SET("profile.feedrate", "100 furlongs")],
     ["profile.feedrate = '100 furlongs' has an unknown unit 'furlongs'", "mm/s"]),
    ("feedrate-per-fortnight", [SET("profile.feedrate", "100 mm/fortnight")],
     ["profile.feedrate = '100 mm/fortnight' has an unknown unit"]),
    ("feedrate-wrong-dimension", [SET("profile.feedrate", "5 s")], ["profile.feedrate = '5 s' is not a feedrate"]),
    ("feedrate-length", [SET("profile.feedrate", "5 mm")], ["profile.feedrate = '5 mm' is not a feedrate"]),
    ("feedrate-accel", [SET("profile.feedrate", "5 mm/s^2")], ["profile.feedrate = '5 mm/s^2' is not a feedrate"]),
    ("feedrate-non-numeric", [SET("profile.feedrate", "fast")],
     ["profile.feedrate = 'fast' is not a number or a quantity with a unit"]),
    ("feedrate-unit-only", [SET("profile.feedrate", "mm/s")], ["profile.feedrate = 'mm/s' is not a number"]),
    ("feedrate-bool", [SET("profile.feedrate", True)], ["profile.feedrate = true is not a number"]),
    ("feedrate-null", [SET("profile.feedrate", None)], ["profile.feedrate = null is not a number"]),
    ("feedrate-list", [SET("profile.feedrate", [100])], ["profile.feedrate = [100] is not a number"]),
    ("feedrate-nan", [SET("profile.feedrate", NAN)], ["profile.feedrate = nan must be a finite number"]),
    ("feedrate-inf", [SET("profile.feedrate", INF)], ["profile.feedrate = inf must be a finite number"]),
    ("feedrate-inf-unit", [SET("profile.feedrate", "1e400 mm/s")], ["profile.feedrate = '1e400 mm/s' must be a finite number"]),
    # ---- accel_time (0 allowed)
    ("accel-time-negative", [SET("profile.accel_time", -0.5)], ["profile.accel_time = -0.5 must be >= 0"]),
    ("accel-time-negative-unit", [SET("profile.accel_time", "-500 ms")], ["profile.accel_time = '-500 ms' must be >= 0"]),
    ("accel-time-unknown-unit", [SET("profile.accel_time", "100 furlongs")],
     ["profile.accel_time = '100 furlongs' has an unknown unit 'furlongs'", "s, ms, us"]),
    ("accel-time-length", [SET("profile.accel_time", "5 mm")], ["profile.accel_time = '5 mm' is not a time", "s, ms, us"]),
    ("accel-time-feedrate", [SET("profile.accel_time", "5 mm/s")], ["profile.accel_time = '5 mm/s' is not a time"]),
    ("accel-time-non-numeric", [SET("profile.accel_time", "soon")],
     ["profile.accel_time = 'soon' is not a number or a quantity with a unit"]),
    ("accel-time-nan", [SET("profile.accel_time", NAN)], ["profile.accel_time = nan must be a finite number"]),
    ("accel-time-inf", [SET("profile.accel_time", INF)], ["profile.accel_time = inf must be a finite number"]),
    # ---- time_constant
    ("time-constant-zero", [SET("profile.time_constant", 0)], ["profile.time_constant = 0 must be > 0"]),
    ("time-constant-negative", [SET("profile.time_constant", -0.1)], ["profile.time_constant = -0.1 must be > 0"]),
    ("time-constant-unknown-unit", [SET("profile.time_constant", "100 furlongs")],
     ["profile.time_constant = '100 furlongs' has an unknown unit 'furlongs'"]),
    ("time-constant-length", [SET("profile.time_constant", "5 mm")], ["profile.time_constant = '5 mm' is not a time"]),
    ("time-constant-non-numeric", [SET("profile.time_constant", "short")],
     ["profile.time_constant = 'short' is not a number"]),
    ("time-constant-inf", [SET("profile.time_constant", INF)], ["profile.time_constant = inf must be a finite number"]),
    # ---- period
    ("period-zero", [SET("interpolator.period", 0)], ["interpolator.period = 0 must be > 0"]),
    ("period-zero-unit", [SET("interpolator.period", "0 ms")], ["interpolator.period = '0 ms' must be > 0"]),
    ("period-negative", [SET("interpolator.period", -0.001)], ["interpolator.period = -0.001 must be > 0"]),
    ("period-negative-unit", [SET("interpolator.period", "-1 ms")], ["interpolator.period = '-1 ms' must be > 0"]),
    ("period-unknown-unit", [SET("interpolator.period", "100 furlongs")],
     ["interpolator.period = '100 furlongs' has an unknown unit 'furlongs'"]),
    ("period-length", [SET("interpolator.period", "5 mm")], ["interpolator.period = '5 mm' is not a time"]),
    ("period-non-numeric", [SET("interpolator.period", "fast")], ["interpolator.period = 'fast' is not a number"]),
    ("period-nan", [SET("interpolator.period", NAN)], ["interpolator.period = nan must be a finite number"]),
    ("period-inf", [SET("interpolator.period", INF)], ["interpolator.period = inf must be a finite number"]),
]


def test_the_base_job_is_valid(tmp_path):
    job = load_job(write_doc(tmp_path, circle()))
    assert isinstance(job, Job)
    assert job.curve.degree == 2
    assert job.profile == ProfileSpec("trapezoidal", 100.0, 0.5, None, "before")
    assert job.interpolator == InterpolatorSpec("taylor2", 0.001)


@pytest.mark.parametrize("mutations, expected", [pytest.param(m, e, id=i) for i, m, e in RULES])
def test_rule(tmp_path, mutations, expected):
    doc = circle()
    for mutate in mutations:
        mutate(doc)
    path = write_doc(tmp_path, doc)
    if expected is None:  # the boundary of a rule: accepted
        load_job(path)
        return
    message = spec_error(path)
    assert_names(message, path, *expected)


def test_rule_table_has_unique_ids():
    ids = [i for i, _, _ in RULES]
    assert len(ids) == len(set(ids))


def test_example_message_is_exact(tmp_path):
    """The message of the module docstring, character for character."""
    doc = circle()
    doc["curve"]["knots"] = [0, 0, 0, 0.5, 0.3, 0.5, 0.75, 1, 1, 1]
    path = write_doc(tmp_path, doc, name="circle.yaml")
    assert spec_error(path) == f"{path}: curve.knots[4] = 0.3 is smaller than curve.knots[3] = 0.5"


def test_negative_weight_message_is_exact(tmp_path):
    doc = circle()
    doc["curve"]["weights"][2] = -0.5
    path = write_doc(tmp_path, doc)
    assert spec_error(path) == f"{path}: curve.weights[2] = -0.5 must be > 0"


def test_first_violation_is_reported(tmp_path):
    """Several broken rules: one message, about the first field checked (curve before profile)."""
    doc = circle()
    doc["curve"]["weights"][4] = 0
    doc["profile"]["feedrate"] = -1
    doc["interpolator"]["period"] = 0
    path = write_doc(tmp_path, doc)
    message = spec_error(path)
    assert "curve.weights[4] = 0" in message
    assert "feedrate" not in message and "period" not in message


# --------------------------------------------------------------------------- bugs found while writing the table


@pytest.mark.parametrize("field", ["degree", "order", "coordinate", "weight", "knot", "feedrate"])
def test_huge_integer_is_a_spec_error(tmp_path, field):
    huge = 10**400
    doc = circle()
    if field == "degree":
        doc["curve"]["degree"] = huge
    elif field == "order":
        del doc["curve"]["degree"]
        doc["curve"]["order"] = huge
    elif field == "coordinate":
        doc["curve"]["control_points"][2][0] = huge
    elif field == "weight":
        doc["curve"]["weights"][2] = huge
    elif field == "knot":
        doc["curve"]["knots"][9] = huge
    else:
        doc["profile"]["feedrate"] = huge
    path = write_doc(tmp_path, doc)
    message = spec_error(path)
    assert_names(message, path)


@pytest.mark.parametrize("section", ["profile", "interpolator"])
@pytest.mark.parametrize("value", [[], "", 0, False], ids=["empty-list", "empty-string", "zero", "false"])
def test_falsy_non_mapping_section_is_refused(tmp_path, section, value):
    doc = circle()
    doc[section] = value
    path = write_doc(tmp_path, doc)
    message = spec_error(path)
    assert_names(message, path, f"{section} = ", "must be a mapping")


def test_unknown_key_with_newline_stays_on_one_line(tmp_path):
    path = write_text(tmp_path, 'curve:\n  degree: 2\n  control_points: [[0, 0], [0, 50], [100, 50]]\n'
                                '  "colour\\nred": 1\n')
    message = spec_error(path)
    assert_names(message, path, "is not a known key")


# --------------------------------------------------------------------------- YAML-level failures


@pytest.mark.parametrize("text, expected", [
    pytest.param("", "the file is empty", id="empty"),
    pytest.param("   \n\n", "the file is empty", id="blank"),
    pytest.param("# only a comment\n", "the file is empty", id="comment-only"),
    pytest.param("- degree: 2\n- control_points: []\n", "must be a mapping with a 'curve' key, not a list", id="list"),
    pytest.param("circle\n", "must be a mapping with a 'curve' key, not a str", id="scalar-string"),
    pytest.param("42\n", "must be a mapping with a 'curve' key, not a int", id="scalar-int"),
    pytest.param("curve: [1, 2\n", "line ", id="unclosed-flow"),
    pytest.param("curve:\n\tdegree: 2\n", "line 2", id="tab-indent"),
    pytest.param("curve:\n  degree: 2\n control_points: []\n", "line ", id="bad-indent"),
    pytest.param("curve: {degree: 2\n", "line ", id="unclosed-mapping"),
    pytest.param("curve: 'unterminated\n", "line ", id="unterminated-quote"),
    pytest.param("curve:\n  degree: 2\n---\ncurve:\n  degree: 3\n", "line ", id="two-documents"),
    pytest.param("curve: !!python/object/apply:os.system ['echo hi']\n", "line 1", id="python-tag"),
    pytest.param("? [1, 2]\n: 3\n", "a mapping key must be a plain value", id="unhashable-key"),
    pytest.param("curve:\n  degree: 2\n  degree: 3\n  control_points: [[0, 0], [1, 1], [2, 0]]\n",
                 "line 3, column 3: duplicate key 'degree' (first at line 2)", id="duplicate-curve-key"),
    pytest.param("curve:\n  degree: 2\n  control_points: [[0, 0], [1, 1], [2, 0]]\nprofile: {}\nprofile: {}\n",
                 "line 5, column 1: duplicate key 'profile' (first at line 4)", id="duplicate-top-key"),
    pytest.param("curve: {degree: 2, degree: 2, control_points: [[0, 0], [1, 1], [2, 0]]}\n",
                 "duplicate key 'degree'", id="duplicate-flow-key"),
    pytest.param("curve:\n  degree: 2\n  control_points: [&p [0, 0], [1, 1], *p]\n",
                 "line 3, column 39: YAML aliases (*name) are not allowed", id="alias"),
    pytest.param("base: &b {degree: 2}\ncurve:\n  <<: *b\n  control_points: [[0, 0], [1, 1], [2, 0]]\n",
                 "YAML aliases (*name) are not allowed", id="merge-alias"),
    pytest.param("a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
                 "c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b]\nd: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c]\n",
                 "YAML aliases (*name) are not allowed", id="alias-bomb"),
    pytest.param("curve:\n  degree: 2\x00\n", "invalid YAML", id="nul-byte"),
])
def test_yaml_level_failure(tmp_path, text, expected):
    path = write_text(tmp_path, text)
    message = spec_error(path)
    assert_names(message, path, expected)


def test_deeply_nested_yaml_is_one_line(tmp_path):
    path = write_text(tmp_path, "curve: " + "[" * 3000 + "]" * 3000 + "\n")
    message = spec_error(path)
    assert_names(message, path)


@pytest.mark.parametrize("raw, byte", [
    pytest.param(b"curve:\n  degree: \xff\n", 0xFF, id="0xff"),
    pytest.param("interpolator:\n  period: 250 µs\n".encode("latin-1"), 0xB5, id="latin-1-micro"),
])
def test_non_utf8_bytes(tmp_path, raw, byte):
    path = tmp_path / "job.yaml"
    path.write_bytes(raw)
    message = spec_error(path)
    offset = raw.index(bytes([byte]))
    assert_names(message, path, "is not UTF-8 text", f"byte 0x{byte:02x} at offset {offset}")


def test_directory(tmp_path):
    message = spec_error(tmp_path)
    assert message == f"{tmp_path}: is a directory, not a YAML file"


def test_missing_file(tmp_path):
    path = tmp_path / "nope.yaml"
    message = spec_error(path)
    assert_names(message, path, "cannot read", "No such file or directory")


def test_utf8_bom_and_crlf_are_accepted(tmp_path):
    path = tmp_path / "job.yaml"
    text = yaml.safe_dump(circle(), sort_keys=False).replace("\n", "\r\n")
    path.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    assert load_job(path).curve.degree == 2


def test_exponent_without_dot_is_a_number(tmp_path):
    """YAML 1.1 reads 1e-3 (no dot) as a string; the job reader still takes it as a number."""
    text = (
        "curve:\n"
        "  degree: 2\n"
        "  control_points: [[0, 0], [0, 5e1], [1e2, 5e1], [1e2, 0], [1e2, -5e1], [0, -5e1], [0, 0]]\n"
        "  weights: [1, 5e-1, 5e-1, 1, 5E-1, 5e-1, 1]\n"
        "  knots: [0, 0, 0, 2.5e-1, 5e-1, 5e-1, 7.5e-1, 1e0, 1e0, 1e0]\n"
        "profile:\n"
        "  type: exponential\n"
        "  feedrate: 1e2\n"
        "  accel_time: 5e-1\n"
        "  time_constant: 1e-1\n"
        "interpolator:\n"
        "  period: 1e-3\n"
    )
    assert isinstance(yaml.safe_load(text)["interpolator"]["period"], str)  # the premise
    job = load_job(write_text(tmp_path, text))
    assert job.interpolator.period == 0.001
    assert job.profile.feedrate == 100.0
    assert job.profile.accel_time == 0.5
    assert job.profile.time_constant == 0.1
    np.testing.assert_array_equal(job.curve.weights, CIRCLE_WEIGHTS)
    np.testing.assert_array_equal(job.curve.knots, CIRCLE_KNOTS)
    np.testing.assert_array_equal(job.curve.control_points, CIRCLE_POINTS)


def test_exponent_without_dot_with_unit(tmp_path):
    doc = circle()
    doc["interpolator"]["period"] = "1e-3 s"
    doc["profile"]["feedrate"] = "6e3 mm/min"
    job = load_job(write_doc(tmp_path, doc))
    assert job.interpolator.period == 0.001
    assert job.profile.feedrate == 100.0


# --------------------------------------------------------------------------- units


@pytest.mark.parametrize("text, kind, value", [
    ("6000 mm/min", "feedrate", 100.0),
    ("6 m/min", "feedrate", 100.0),
    ("100 mm/s", "feedrate", 100.0),
    ("100mm/s", "feedrate", 100.0),
    ("0.1 m/s", "feedrate", 100.0),
    ("100", "feedrate", 100.0),
    (100, "feedrate", 100.0),
    (2.5, "feedrate", 2.5),
    ("3000 mm/min", "feedrate", 50.0),
    ("60 in/min", "feedrate", 25.4),
    ("500 ms", "time", 0.5),
    ("0.5 s", "time", 0.5),
    ("1 ms", "time", 0.001),
    ("0.5 ms", "time", 0.0005),
    ("200 ms", "time", 0.2),
    ("250 us", "time", 0.00025),
    ("250 µs", "time", 0.00025),   # U+00B5 MICRO SIGN
    ("250 μs", "time", 0.00025),   # U+03BC GREEK SMALL LETTER MU
    ("500 us", "time", 0.0005),
    ("1 min", "time", 60.0),
    ("1e-3", "time", 0.001),
    ("1 um", "length", 0.001),
    ("1 µm", "length", 0.001),
    ("2 mm", "length", 2.0),
    ("1 nm", "length", 1e-6),
    ("1000 mm/s^2", "accel", 1000.0),
    ("1000 mm/s2", "accel", 1000.0),
    ("1000 mm/s²", "accel", 1000.0),
    ("1 m/s^2", "accel", 1000.0),
    ("5000 mm/s^3", "jerk", 5000.0),
])
def test_parse_quantity_exact(text, kind, value):
    assert parse_quantity(text, kind) == value


@pytest.mark.parametrize("text, kind, expected", [
    ("100 furlongs", "feedrate", "unknown unit 'furlongs'"),
    ("5 mm", "time", "is not a time"),
    ("5 s", "length", "is not a length"),
    ("5 mm/s", "accel", "is not an acceleration"),
    ("5 mm/s^2", "feedrate", "is not a feedrate"),
    ("fast", "feedrate", "is not a number or a quantity with a unit"),
    (None, "time", "is not a number or a quantity with a unit"),
    (True, "time", "is not a number or a quantity with a unit"),
])
def test_parse_quantity_refuses(text, kind, expected):
    with pytest.raises(ValueError) as info:
        parse_quantity(text, kind)
    assert expected in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("section, key, text, attr, value", [
    ("profile", "feedrate", "6000 mm/min", "feedrate", 100.0),
    ("profile", "feedrate", "6 m/min", "feedrate", 100.0),
    ("profile", "feedrate", "100 mm/s", "feedrate", 100.0),
    ("profile", "accel_time", "500 ms", "accel_time", 0.5),
    ("profile", "accel_time", 0, "accel_time", 0.0),
    ("profile", "accel_time", "0 ms", "accel_time", 0.0),
    ("profile", "time_constant", "50 ms", "time_constant", 0.05),
    ("profile", "time_constant", None, "time_constant", None),
    ("interpolator", "period", "1 ms", "period", 0.001),
    ("interpolator", "period", "250 us", "period", 0.00025),
    ("interpolator", "period", "250 µs", "period", 0.00025),
    ("interpolator", "period", 0.002, "period", 0.002),
])
def test_quantities_in_a_job(tmp_path, section, key, text, attr, value):
    doc = circle()
    doc[section][key] = text
    if key == "time_constant":
        doc["profile"]["type"] = "exponential"  # the only profile that reads it
    job = load_job(write_doc(tmp_path, doc))
    assert getattr(getattr(job, section), attr) == value


@pytest.mark.parametrize("kind, method", [(k, m) for k in ("trapezoidal", "exponential", "bell")
                                          for m in ("taylor1", "taylor2", "rk4", "exact")])
def test_every_choice_is_accepted(tmp_path, kind, method):
    doc = circle()
    doc["profile"]["type"] = kind
    doc["interpolator"]["method"] = method
    job = load_job(write_doc(tmp_path, doc))
    assert (job.profile.type, job.interpolator.method) == (kind, method)


# --------------------------------------------------------------------------- defaults


def test_defaults_when_sections_are_absent(tmp_path):
    doc = {"curve": circle()["curve"]}
    job = load_job(write_doc(tmp_path, doc))
    assert job.profile.type == "trapezoidal"
    assert job.profile.feedrate == 100.0
    assert job.profile.accel_time == 0.5
    assert job.profile.time_constant is None
    assert job.profile.tau == 0.125
    assert job.profile.accdec == "before"
    assert job.interpolator.method == "taylor2"
    assert job.interpolator.period == 0.001


def test_empty_sections_give_defaults(tmp_path):
    path = write_text(tmp_path, yaml.safe_dump({"curve": circle()["curve"]}) + "profile:\ninterpolator: {}\n")
    job = load_job(path)
    assert job.profile == ProfileSpec()
    assert job.interpolator == InterpolatorSpec()


def test_default_knots_are_clamped_uniform(tmp_path):
    doc = circle()
    del doc["curve"]["knots"]
    job = load_job(write_doc(tmp_path, doc))
    np.testing.assert_allclose(job.curve.knots, [0, 0, 0, 0.2, 0.4, 0.6, 0.8, 1, 1, 1], rtol=0, atol=1e-15)
    assert job.curve.knots[0] == 0.0 and job.curve.knots[-1] == 1.0


def test_default_knots_degree_equal_to_points_minus_one(tmp_path):
    doc = {"curve": {"degree": 3, "control_points": [[0, 0], [1, 2], [3, 2], [4, 0]]}}
    job = load_job(write_doc(tmp_path, doc))
    np.testing.assert_array_equal(job.curve.knots, [0, 0, 0, 0, 1, 1, 1, 1])


def test_default_weights_are_one(tmp_path):
    doc = circle()
    del doc["curve"]["weights"]
    job = load_job(write_doc(tmp_path, doc))
    np.testing.assert_array_equal(job.curve.weights, np.ones(7))


def test_order_is_degree_plus_one(tmp_path):
    doc = circle()
    del doc["curve"]["degree"]
    doc["curve"]["order"] = 3
    assert load_job(write_doc(tmp_path, doc)).curve.degree == 2


def test_integral_float_degree_is_accepted(tmp_path):
    doc = circle()
    doc["curve"]["degree"] = 2.0
    job = load_job(write_doc(tmp_path, doc))
    assert job.curve.degree == 2 and isinstance(job.curve.degree, int)


def test_degree_25_is_accepted(tmp_path):
    doc = {"curve": {"degree": 25, "control_points": [[i, (-1) ** i] for i in range(26)]}}
    assert load_job(write_doc(tmp_path, doc)).curve.degree == 25


def test_3d_job(tmp_path):
    doc = circle()
    doc["curve"]["control_points"] = [p + [1.5] for p in CIRCLE_POINTS]
    job = load_job(write_doc(tmp_path, doc))
    assert job.curve.control_points.shape == (7, 3)


def test_arrays_are_frozen_and_source_is_kept(tmp_path):
    path = write_doc(tmp_path, circle())
    job = load_job(path)
    assert job.source == str(path)
    for arr in (job.curve.control_points, job.curve.weights, job.curve.knots):
        with pytest.raises(ValueError):
            arr[0] = 1.0


# --------------------------------------------------------------------------- --profile FILE and overrides


@pytest.fixture
def job_file(tmp_path):
    doc = circle()
    doc["profile"] = {"type": "bell", "feedrate": "80 mm/s", "accel_time": "300 ms", "accdec": "before"}
    doc["interpolator"] = {"method": "rk4", "period": "2 ms"}
    return write_doc(tmp_path, doc)


def test_profile_file_overrides_field_by_field(tmp_path, job_file):
    pfile = write_doc(tmp_path, {"profile": {"feedrate": "50 mm/s"}, "interpolator": {"period": "500 us"}},
                      name="fast.yaml")
    job = load_job(job_file, profile_file=pfile)
    assert job.profile.feedrate == 50.0         # from the profile file
    assert job.profile.type == "bell"           # from the job
    assert job.profile.accel_time == 0.3        # from the job
    assert job.interpolator.period == 0.0005    # from the profile file
    assert job.interpolator.method == "rk4"     # from the job


def test_profile_file_with_only_interpolator(tmp_path, job_file):
    pfile = write_doc(tmp_path, {"interpolator": {"method": "exact"}}, name="p.yaml")
    job = load_job(job_file, profile_file=pfile)
    assert job.interpolator == InterpolatorSpec("exact", 0.002)
    assert job.profile.feedrate == 80.0


def test_command_line_wins_over_both(tmp_path, job_file):
    pfile = write_doc(tmp_path, {"profile": {"feedrate": "50 mm/s", "type": "exponential"}}, name="p.yaml")
    job = load_cli(job_file, profile_file=pfile, overrides={
        "feedrate": "1200 mm/min", "accel_time": "0", "period": "250 us", "time_constant": "10 ms",
        "profile_type": None, "accdec": "after", "interpolator": "taylor1"})
    assert job.profile.feedrate == 20.0
    assert job.profile.type == "exponential"    # None overrides are ignored: the profile file's value stays
    assert job.profile.accel_time == 0.0
    assert job.profile.time_constant == 0.01
    assert job.profile.accdec == "after"
    assert job.interpolator == InterpolatorSpec("taylor1", 0.00025)


def test_none_overrides_change_nothing(job_file):
    plain = load_job(job_file)
    job = load_cli(job_file, overrides={k: None for k in ("feedrate", "period", "profile_type")})
    assert (job.profile, job.interpolator) == (plain.profile, plain.interpolator)


@pytest.mark.parametrize("option, value, expected", [
    ("feedrate", "-5", "--feedrate: profile.feedrate = '-5' must be > 0"),
    ("feedrate", "0", "--feedrate: profile.feedrate = '0' must be > 0"),
    ("feedrate", "100 furlongs", "--feedrate: profile.feedrate = '100 furlongs' has an unknown unit 'furlongs'"),
    ("feedrate", "5 s", "--feedrate: profile.feedrate = '5 s' is not a feedrate"),
    ("feedrate", "fast", "--feedrate: profile.feedrate = 'fast' is not a number"),
    ("accel_time", "-1", "--accel-time: profile.accel_time = '-1' must be >= 0"),
    ("accel_time", "5 mm", "--accel-time: profile.accel_time = '5 mm' is not a time"),
    ("time_constant", "0", "--time-constant: profile.time_constant = '0' must be > 0"),
    ("time_constant", "x", "--time-constant: profile.time_constant = 'x' is not a number"),
    ("period", "0", "--period: interpolator.period = '0' must be > 0"),
    ("period", "-1 ms", "--period: interpolator.period = '-1 ms' must be > 0"),
    ("period", "1 fortnight", "--period: interpolator.period = '1 fortnight' has an unknown unit 'fortnight'"),
    ("period", "5 mm", "--period: interpolator.period = '5 mm' is not a time"),
    ("profile_type", "scurve", "--profile-type: profile.type = 'scurve' is not one of"),
    ("accdec", "during", "--accdec: profile.accdec = 'during' is not one of"),
    ("interpolator", "euler", "--interpolator: interpolator.method = 'euler' is not one of"),
])
def test_override_error_names_the_option(tmp_path, job_file, option, value, expected):
    with pytest.raises(SpecError) as info:
        load_cli(job_file, overrides={option: value})
    message = check_message(info.value)
    assert message.startswith(expected), message


def test_override_error_wins_over_profile_file_origin(tmp_path, job_file):
    pfile = write_doc(tmp_path, {"interpolator": {"period": "1 ms"}}, name="p.yaml")
    with pytest.raises(SpecError) as info:
        load_cli(job_file, profile_file=pfile, overrides={"period": "0"})
    assert check_message(info.value).startswith("--period: interpolator.period = '0'")


@pytest.mark.parametrize("pdoc, expected", [
    ({"profile": {"feedrate": -1}}, "profile.feedrate = -1 must be > 0"),
    ({"profile": {"type": "scurve"}}, "profile.type = 'scurve' is not one of"),
    ({"profile": {"accel_time": "5 mm"}}, "profile.accel_time = '5 mm' is not a time"),
    ({"interpolator": {"period": 0}}, "interpolator.period = 0 must be > 0"),
    ({"interpolator": {"method": "euler"}}, "interpolator.method = 'euler' is not one of"),
    ({"profile": {"speed": 5}}, "profile.speed is not a known key"),
    ({"interpolator": {"dt": 5}}, "interpolator.dt is not a known key"),
    ({"curve": {"degree": 2}}, "curve is not a known key (known: profile, interpolator)"),
    ({"profile": [1, 2]}, "profile = [1, 2] must be a mapping"),
    ({"profile": None}, "profile = null must be a mapping"),
])
def test_profile_file_error_names_the_profile_file(tmp_path, job_file, pdoc, expected):
    pfile = write_doc(tmp_path, pdoc, name="machine.yaml")
    with pytest.raises(SpecError) as info:
        load_job(job_file, profile_file=pfile)
    message = check_message(info.value)
    assert_names(message, pfile, expected)


@pytest.mark.parametrize("text, expected", [
    ("", "the file is empty"),
    ("[1, 2]\n", "not a list"),
    ("profile: {feedrate: 1, feedrate: 2}\n", "duplicate key 'feedrate'"),
    ("profile: &p {feedrate: 1}\ninterpolator: *p\n", "aliases"),
])
def test_profile_file_yaml_error_names_the_profile_file(tmp_path, job_file, text, expected):
    pfile = write_text(tmp_path, text, name="machine.yaml")
    with pytest.raises(SpecError) as info:
        load_job(job_file, profile_file=pfile)
    assert_names(check_message(info.value), pfile, expected)


def test_missing_profile_file(tmp_path, job_file):
    pfile = tmp_path / "missing.yaml"
    with pytest.raises(SpecError) as info:
        load_job(job_file, profile_file=pfile)
    assert_names(check_message(info.value), pfile, "cannot read")


def test_job_error_still_names_the_job_file_with_a_profile_file(tmp_path):
    doc = circle()
    doc["curve"]["weights"][1] = 0
    doc["profile"]["feedrate"] = -3
    path = write_doc(tmp_path, doc)
    pfile = write_doc(tmp_path, {"interpolator": {"period": "1 ms"}}, name="p.yaml")
    message = spec_error(path, profile_file=pfile)
    assert_names(message, path, "curve.weights[1] = 0 must be > 0")
    doc["curve"]["weights"][1] = 0.5
    path = write_doc(tmp_path, doc)
    message = spec_error(path, profile_file=pfile)
    assert_names(message, path, "profile.feedrate = -3 must be > 0")


# --------------------------------------------------------------------------- NurbsCurve(...) directly


def test_nurbs_curve_valid():
    c = NurbsCurve(2, CIRCLE_POINTS, CIRCLE_WEIGHTS, CIRCLE_KNOTS)
    assert math.isclose(c.length, 100 * math.pi, rel_tol=0, abs_tol=1e-9)


@pytest.mark.parametrize("args, expected", [
    pytest.param((0, CIRCLE_POINTS), "NurbsCurve: curve.degree = 0 must be >= 1", id="degree-0"),
    pytest.param((2.5, CIRCLE_POINTS), "NurbsCurve: curve.degree = 2.5 must be an integer", id="degree-2.5"),
    pytest.param((26, CIRCLE_POINTS), "NurbsCurve: curve.degree = 26 is above the supported maximum", id="degree-26"),
    pytest.param((2, []), "NurbsCurve: curve.control_points = [] must be a non-empty list", id="no-points"),
    pytest.param((2, [[0, 0], [1, 1]]), "NurbsCurve: curve.control_points", id="too-few"),
    pytest.param((2, [[0, 0, 0, 0]] * 3), "NurbsCurve: curve.control_points[0] = [0, 0, 0, 0] must be a point",
                 id="4d"),
    pytest.param((2, [0, 1, 2]), "NurbsCurve: curve.control_points[0] = 0 must be a point", id="flat-list"),
    pytest.param((2, [[0, 0], [NAN, 1], [2, 0]]), "NurbsCurve: curve.control_points[1][0] = nan must be a finite",
                 id="nan-point"),
    pytest.param((2, CIRCLE_POINTS, [1, 0.5, -0.5, 1, 0.5, 0.5, 1]), "NurbsCurve: curve.weights[2] = -0.5 must be > 0",
                 id="negative-weight"),
    pytest.param((2, CIRCLE_POINTS, [1, 1]), "NurbsCurve: curve.weights", id="weight-count"),
    pytest.param((2, CIRCLE_POINTS, None, [0, 0, 0, 0.5, 0.3, 0.5, 0.75, 1, 1, 1]),
                 "NurbsCurve: curve.knots[4] = 0.3 is smaller than curve.knots[3] = 0.5", id="decreasing-knots"),
    pytest.param((2, CIRCLE_POINTS, None, [0, 0, 1]), "NurbsCurve: curve.knots", id="knot-count"),
])
def test_nurbs_curve_bad_input_is_a_spec_error(args, expected):
    with pytest.raises(ValueError) as info:
        NurbsCurve(*args)
    message = check_message(info.value)
    assert message.startswith(expected), message


@pytest.mark.parametrize("args", [
    pytest.param((2, [[0, 0], [1, 1, 1], [2, 0]]), id="ragged-points"),
    pytest.param((2, [["a", 0], [1, 1], [2, 0]]), id="string-coordinate"),
    pytest.param((2, [[0, 0], [1, 1], [2, 0]], [1, "x", 1]), id="string-weight"),
    pytest.param((2, [[0, 0], [1, 1], [2, 0]], None, [0, 0, 0, "one", 1, 1]), id="string-knot"),
])
def test_nurbs_curve_unconvertible_input_is_a_spec_error(args):
    with pytest.raises(SpecError) as info:
        NurbsCurve(*args)
    assert check_message(info.value).startswith("NurbsCurve: curve.")


# =========================================================================== large files: the event reader

TRICKY_PLAIN = ["0", "-0", "+1", "010", "0o17", "0x1F", "0b101", "1_000", "1:30", "190:20:30", "1e-3", "1.0e+3",
                "1.5e3", "12e03", "1.", ".5", "-.5", "+.5", "1.2.3", ".inf", "-.Inf", ".NaN", "yes", "No", "off",
                "ON", "~", "null", "Null", "true", "False", "2001-12-14", "2001-12-14t21:59:43.10-05:00",
                "1 ms", "6000 mm/min", "trapezoidal", "9" * 30, "-" + "9" * 20 + ".5e+10", "0.0000001", "1e400"]


def _canonical(value):
    """A comparable form: NaN equals NaN, and 1, 1.0 and True stay apart."""
    if isinstance(value, dict):
        return ("map", [(_canonical(k), _canonical(v)) for k, v in value.items()])
    if isinstance(value, list):
        return ("seq", [_canonical(v) for v in value])
    if isinstance(value, float) and value != value:
        return ("float", "nan")
    return (type(value).__name__, value)


def _same_as_the_full_loader(text):
    try:
        fast = _fast_yaml(text)
    except _Unusual:
        return False
    assert _canonical(fast) == _canonical(yaml.load(text, Loader=_Loader)), text  # noqa: S506 - a SafeLoader
    return True


SCALARS = st.one_of(st.integers(), st.floats(allow_nan=True), st.booleans(), st.none(), st.text(max_size=12),
                    st.sampled_from(TRICKY_PLAIN))
DOCS = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=5) |
                    st.dictionaries(st.text(max_size=6) | st.integers(), inner, max_size=5), max_leaves=30)


@budgets(quick=60, full=300)
def test_event_reader_reads_what_the_full_loader_reads(budget):
    @settings(max_examples=budget, deadline=None)
    @given(doc=DOCS, flow=st.booleans())
    def check(doc, flow):
        _same_as_the_full_loader(yaml.safe_dump(doc, default_flow_style=flow, allow_unicode=True))

    check()


@pytest.mark.parametrize("plain", TRICKY_PLAIN)
def test_event_reader_resolves_plain_scalars_as_yaml_1_1(plain):
    assert _same_as_the_full_loader(f"a: {plain}\nb: [{plain}, {plain}]\n")


@pytest.mark.parametrize("text", [
    "a: &x 1\nb: *x\n", "a: &x 1\n", "a: !!str 1\n", "a: !custom 1\n", "base: &b {x: 1}\nc: {<<: *b}\n",
    "a: {<<: {x: 1}}\n", "a: 1\na: 2\n", "a: 1\n---\nb: 2\n", "a: [1, 2\n", "a: b: c\n", "[1]: 2\n",
    "a: " + "[" * 70 + "]" * 70 + "\n", "a: " + "9" * 5000 + "\n",
], ids=["alias", "anchor", "tag", "custom-tag", "merge-alias", "merge", "duplicate", "two-documents",
        "unclosed", "bad-mapping", "sequence-key", "deep", "5000-digits"])
def test_event_reader_leaves_the_unusual_to_the_full_loader(text):
    with pytest.raises(_Unusual):
        _fast_yaml(text)


def test_a_large_file_reads_alike_and_fails_alike(tmp_path):
    points = ",".join(f"[{i}, {(i * 7919) % 1000 / 10}]" for i in range(8000))
    text = f"curve:\n  degree: 3\n  control_points: [{points}]\nprofile: {{feedrate: 6000 mm/min}}\n"
    assert len(text) > FAST_YAML_BYTES
    path = tmp_path / "big.yaml"
    path.write_text(text)
    assert read_yaml(path) == yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader
    # what only the full loader reads still gets its message, with the line
    path.write_text(text + "profile: {feedrate: 1}\n")
    with pytest.raises(SpecError, match=r"big\.yaml: line 5, column 1: duplicate key 'profile' \(first at line 4\)"):
        read_yaml(path)
    path.write_text(text + "extra: *anchor\n")
    with pytest.raises(SpecError, match=r"line 5, column 8: YAML aliases"):
        read_yaml(path)
