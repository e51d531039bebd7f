"""One NURBS curve: the `curve:` section of a job and the `nurbs:` block of a path."""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from .rules import MAX_CONTROL_POINTS, Where, finite, integer, mapping, number_list
from .units import show

MAX_DEGREE = 25
MAX_COORDINATE = 1e12  # mm: squares and cross products of coordinates stay far from overflow
MAX_WEIGHT_RATIO = 1e6  # largest weight over smallest (see validate_curve)
# Each weight within [MIN_WEIGHT, MAX_WEIGHT] (see validate_curve).  The kernels multiply weights
# into homogeneous points w·P (|P| <= MAX_COORDINATE) and their u-derivative tables (factors up to
# ((degree / MIN_KNOT_SPAN)^3 ~ 1.6e94), and the contour search multiplies two of them together:
# w_i·w_j·d² and |w_i (P_i - q)|·|w_j (P_j - q)| with distances d down to its 1e-9 mm tolerance.
# Those products must stay normal doubles: w² · (1e-9 mm)² >= 2.2e-308 needs w >= 1.5e-145, and
# (w · 2e12 mm)² <= 1.8e308 (and 1.3e107·w finite for the third-derivative table) needs
# w <= 6e141.  [1e-100, 1e100] keeps forty orders of magnitude of margin for the sums, the
# dimension and the binomial factors; a subnormal weight (5e-324 makes every w·P of an ordinary
# coordinate vanish or lose all its digits) is far outside it.  Scaling every weight by one
# factor does not change the curve, so any curve can be brought inside.
MIN_WEIGHT = 1e-100
MAX_WEIGHT = 1e100
MAX_KNOT = 1e30  # |u| bound: with MIN_KNOT_SPAN it keeps the third derivative in u finite
MIN_KNOT_SPAN = 1e-30
MAX_U_RESOLUTION = 1e-6  # mm of curve between adjacent representable u values (see _check_resolution)


@dataclass(frozen=True)
class CurveSpec:
    """A validated NURBS: degree p, control points (n+1, dim), weights (n+1,), knots (n+p+2,)."""

    degree: int
    control_points: np.ndarray
    weights: np.ndarray
    knots: np.ndarray

    def __post_init__(self):
        for arr in (self.control_points, self.weights, self.knots):
            arr.setflags(write=False)

    @property
    def fingerprint(self) -> str:
        """16 hex digits that name this curve exactly (degree, control points, weights, knots).

        A binary stream carries it, so that `simulate` can tell a stream planned from another job.
        The sign of a zero does not enter it (:func:`fingerprint_bytes`).
        """
        import hashlib

        digest = hashlib.sha1(b"%d" % self.degree)
        for arr in (self.control_points, self.weights, self.knots):
            digest.update(b"%d," % arr.shape[-1] if arr.ndim > 1 else b"1,")
            digest.update(fingerprint_bytes(arr))
        return digest.hexdigest()[:16]


def fingerprint_bytes(values) -> bytes:
    """The bytes a fingerprint hashes of *values*: little-endian doubles, -0.0 written as 0.0.

    The two zeros are the same coordinate; a writer that prints one as "-0.0" (a clockwise
    arc's normal, a program's X-0) must not make the same path another path."""
    return (np.ascontiguousarray(values, dtype="<f8") + 0.0).tobytes()  # -0.0 + 0.0 is +0.0


CURVE_KEYS = ("degree", "order", "control_points", "weights", "knots")


def validate_curve(raw: Any, where: Where, name: str = "curve") -> CurveSpec:
    """A NURBS from its YAML mapping; *name* is the field that holds it (``curve``, ``path.blocks[3].nurbs``)."""
    prefix = name
    raw = mapping(where, name, raw, CURVE_KEYS)
    if "degree" in raw and "order" in raw:
        raise where.fail(f"{prefix}.order", raw["order"], f"is given together with {prefix}.degree; give one (order = degree + 1)")
    if "degree" in raw:
        degree = integer(where, f"{prefix}.degree", raw["degree"])
        if degree < 1:
            raise where.fail(f"{prefix}.degree", raw["degree"], "must be >= 1")
        if degree > MAX_DEGREE:
            raise where.fail(f"{prefix}.degree", raw["degree"], f"is above the supported maximum of {MAX_DEGREE}")
    elif "order" in raw:
        order = integer(where, f"{prefix}.order", raw["order"])
        if order < 2:
            raise where.fail(f"{prefix}.order", raw["order"], "must be >= 2 (order = degree + 1)")
        if order > MAX_DEGREE + 1:
            raise where.fail(f"{prefix}.order", raw["order"], f"is above the supported maximum of {MAX_DEGREE + 1}")
        degree = order - 1
    else:
        raise where.fail(prefix, "", "needs a degree (or order = degree + 1)", shown=False)

    if "control_points" not in raw:
        raise where.fail(prefix, "", "needs control_points", shown=False)
    cps = raw["control_points"]
    if not isinstance(cps, list) or not cps:
        raise where.fail(f"{prefix}.control_points", cps, "must be a non-empty list of [x, y] or [x, y, z] points")
    if len(cps) > MAX_CONTROL_POINTS:
        raise where.fail(f"{prefix}.control_points", f"<{len(cps)} points>", f"has more than the limit of {MAX_CONTROL_POINTS} points")
    dim = None
    points = []
    for i, cp in enumerate(cps):
        cname = f"{prefix}.control_points[{i}]"
        if not isinstance(cp, list) or len(cp) not in (2, 3):
            raise where.fail(cname, cp, "must be a point [x, y] or [x, y, z]")
        if dim is None:
            dim = len(cp)
        elif len(cp) != dim:
            raise where.fail(cname, cp, f"has {len(cp)} coordinates; {prefix}.control_points[0] has {dim}")
        coords = [finite(where, f"{cname}[{j}]", c) for j, c in enumerate(cp)]
        for j, c in enumerate(coords):
            if abs(c) > MAX_COORDINATE:
                raise where.fail(f"{cname}[{j}]", cp[j], f"mm is beyond the supported range of +-{MAX_COORDINATE:g} mm")
        points.append(coords)
    control_points = np.array(points, dtype=float)
    n_ctrl = len(points)
    if n_ctrl < degree + 1:
        raise where.fail(f"{prefix}.control_points", f"<{n_ctrl} points>",
                         f"are too few for degree {degree} (need at least degree + 1 = {degree + 1})")

    if "weights" in raw:
        weights = number_list(where, f"{prefix}.weights", raw["weights"])
        if len(weights) != n_ctrl:
            raise where.fail(f"{prefix}.weights", f"<{len(weights)} values>", f"must have one weight per control point ({n_ctrl})")
        for i, w in enumerate(weights):
            if not w > 0:
                raise where.fail(f"{prefix}.weights[{i}]", raw["weights"][i], "must be > 0")
            if not MIN_WEIGHT <= w <= MAX_WEIGHT:
                kind = "subnormal, " if w < sys.float_info.min else ""
                raise where.fail(f"{prefix}.weights[{i}]", raw["weights"][i],
                                 f"is {kind}outside the supported range [{MIN_WEIGHT:g}, {MAX_WEIGHT:g}] (products of "
                                 "weights and coordinates would underflow or overflow); scale all the weights by one "
                                 "factor (the curve does not change)")
        lo, hi = int(np.argmin(weights)), int(np.argmax(weights))
        if weights[hi] / weights[lo] > MAX_WEIGHT_RATIO:
            raise where.fail(f"{prefix}.weights[{hi}]", raw["weights"][hi],
                             f"is {weights[hi] / weights[lo]:.3g} times {prefix}.weights[{lo}] = {show(raw['weights'][lo])}; "
                             f"the supported ratio is at most {MAX_WEIGHT_RATIO:g} (beyond it part of the curve is "
                             "squeezed into a sliver of u that double precision cannot step through evenly)")
    else:
        weights = np.ones(n_ctrl)

    n_knots = n_ctrl + degree + 1
    if "knots" in raw:
        knots = number_list(where, f"{prefix}.knots", raw["knots"])
        _check_knots(where, knots, degree, n_ctrl, raw["knots"], prefix)
    else:  # clamped, uniform on [0, 1]
        inner = np.linspace(0.0, 1.0, n_ctrl - degree + 1)
        knots = np.concatenate([np.zeros(degree), inner, np.ones(degree)])
    assert len(knots) == n_knots
    _check_resolution(where, control_points, weights, knots, degree, prefix)
    return CurveSpec(degree, control_points, weights, knots)


def _check_resolution(where: Where, points: np.ndarray, weights: np.ndarray, knots: np.ndarray, p: int,
                      prefix: str = "curve") -> None:
    """The knot domain must keep u resolvable and the derivatives in u finite.

    Scaling the knots does not change the curve, but u is what the interpolator
    steps: a domain too narrow for its magnitude ([1, 1 + 1e-15]) has a handful of
    representable u values, and a span of 1e-300 makes |P'|² overflow.  Adjacent
    doubles u and u + ulp(u) lie about |C'(u)|·ulp(u) apart on the curve; the rule is

        max over the domain of |C'(u)|·ulp(u)  <=  max(1e-6 mm, 1e-12 · control polygon length)

    with the maximum taken over samples of every span (a polynomial span whose
    hodograph bounds it within the limit is cleared unsampled) (:func:`_max_step_per_ulp`: both span ends and
    17 points per span, refined wherever the chord between two samples shows the
    speed peaking between them).  Not the polygon's average
    speed: a rational curve with a large weight moves through most of its length in
    a sliver of u, where |C'| is many times the average.
    """
    a, b = float(knots[p]), float(knots[-p - 1])
    name = f"{prefix}.knots"
    if abs(a) > MAX_KNOT or abs(b) > MAX_KNOT:
        raise where.fail(name, "", f"domain [{a:g}, {b:g}] is beyond +-{MAX_KNOT:g}; rescale the knots "
                         "(the curve does not change)", shown=False)
    spans = np.diff(knots)
    narrow = spans[(spans > 0) & (spans < MIN_KNOT_SPAN)]
    if narrow.size:
        raise where.fail(name, "", f"domain [{a:g}, {b:g}] has a knot span of {narrow[0]:g}, narrower than "
                         f"{MIN_KNOT_SPAN:g}; merge those knots or rescale them", shown=False)
    polygon = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
    # 1 nm, or 1e-12 of the path on paths over a kilometre (whose coordinates themselves are
    # not finer than that); a domain [0, 1] always passes
    allowed = max(MAX_U_RESOLUTION, 1e-12 * polygon)
    step, at = _max_step_per_ulp(points, weights, knots, p, allowed)
    if not step <= allowed:
        raise where.fail(name, "", f"domain [{a!r}, {b!r}] is too narrow for its magnitude: adjacent values of u "
                         f"lie up to {step:.3g} mm apart on the curve (max |C'(u)|·ulp(u), near u = {at!r}; at most "
                         f"{allowed:.3g} mm is supported); shift or rescale the knots (the curve does not change)",
                         shown=False)


RESOLUTION_SAMPLES = 17  # per knot span, both ends included (see _max_step_per_ulp)
RESOLUTION_ROUNDS = 12  # refinements of the intervals where the speed may peak between samples
_RESOLUTION_CHUNK = 1 << 16  # samples evaluated at once (memory: tens of MB at degree 25)


def _speeds(points, weights, knots, p, span, u):
    """|C'(u)| at parameters u, each on its knot span (the span's polynomial: u may be its right end).

    Plain numpy (validation runs before the compiled kernels load): Cox–de Boor
    for the basis of degree p - 1 and p, the derivative from the former, then the
    quotient rule on the homogeneous sums.
    """
    m = u.shape[0]
    low = cur = np.ones((m, 1))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for d in range(1, p + 1):
            prev = low = cur
            cur = np.zeros((m, d + 1))
            for r in range(d + 1):
                i = span - d + r
                if r >= 1:
                    den = knots[i + d] - knots[i]
                    cur[:, r] += np.where(den > 0, (u - knots[i]) / np.where(den > 0, den, 1.0), 0.0) * prev[:, r - 1]
                if r <= d - 1:
                    den = knots[i + d + 1] - knots[i + 1]
                    cur[:, r] += np.where(den > 0, (knots[i + d + 1] - u) / np.where(den > 0, den, 1.0), 0.0) * prev[:, r]
        N = cur  # degree p; low is degree p - 1
        dN = np.zeros((m, p + 1))
        for r in range(p + 1):
            i = span - p + r
            if r >= 1:
                den = knots[i + p] - knots[i]
                dN[:, r] += np.where(den > 0, p / np.where(den > 0, den, 1.0), 0.0) * low[:, r - 1]
            if r <= p - 1:
                den = knots[i + p + 1] - knots[i + 1]
                dN[:, r] -= np.where(den > 0, p / np.where(den > 0, den, 1.0), 0.0) * low[:, r]
        idx = span[:, None] - p + np.arange(p + 1)[None, :]
        w = weights[idx]
        P = points[idx]
        W = (N * w).sum(axis=1)
        dW = (dN * w).sum(axis=1)
        A = np.einsum("mr,mrc->mc", N * w, P)
        dA = np.einsum("mr,mrc->mc", dN * w, P)
        C = A / W[:, None]
        D = (dA - dW[:, None] * C) / W[:, None]
        return np.sqrt((D * D).sum(axis=1)), C


def _max_step_per_ulp(points, weights, knots, p, allowed: float = 0.0) -> tuple[float, float]:
    """(max of |C'(u)|·ulp(u) over samples of the domain, the u where it is), mm.

    A polynomial span (equal weights) whose hodograph's control points bound the
    product by *allowed* is cleared without samples.  Every other non-empty knot span is sampled at RESOLUTION_SAMPLES points, both ends
    included (the speed of a rational piece peaks at an end or near the control
    point of a large weight).  Between two samples the mean value theorem gives
    max |C'| >= chord / Δu; where that exceeds both samples' speeds by a quarter
    the speed peaks in between, and the interval is sampled again, up to
    RESOLUTION_ROUNDS times (each round narrows the peak 16-fold).  The chords
    count as well as the speeds, so the result is a lower bound of the true
    maximum that the refinement makes tight.
    """
    n = points.shape[0] - 1
    idx = np.flatnonzero(knots[p:n + 1] < knots[p + 1:n + 2]) + p  # non-empty spans
    best, best_u = 0.0, float(knots[p])
    # a span whose p + 1 weights are equal is a polynomial piece: its hodograph's control points
    # p (P_{j+1} - P_j) / (U_{j+p+1} - U_{j+1}) bound |C'| exactly (convex hull), no sampling needed
    changes = np.concatenate([[0], np.cumsum(weights[1:] != weights[:-1])])  # O(n) memory, any degree
    plain = changes[idx] == changes[idx - p]  # weights span - p .. span all equal
    if plain.any():
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            jj = np.arange(n)
            hodo = p * np.linalg.norm(points[1:] - points[:-1], axis=1) / (knots[jj + p + 1] - knots[jj + 1])
            hodo = np.nan_to_num(hodo, nan=np.inf)
            sp = idx[plain]
            top = hodo[sp - p]
            for r in range(1, p):  # j = span - p .. span - 1
                top = np.maximum(top, hodo[sp - p + r])
            step = top * np.spacing(np.maximum(np.abs(knots[sp]), np.abs(knots[sp + 1])))
        clear = step <= allowed  # the bound clears these; the others are sampled like rational spans
        if clear.any():
            k = int(np.argmax(np.where(clear, step, -1.0)))
            best, best_u = float(step[k]), float(knots[sp[k]])
        cleared = np.zeros(idx.shape[0], dtype=bool)
        cleared[np.flatnonzero(plain)[clear]] = True
        idx = idx[~cleared]
    t = np.linspace(0.0, 1.0, RESOLUTION_SAMPLES)
    lo, hi = knots[idx], knots[idx + 1]
    spans = idx
    for _ in range(RESOLUTION_ROUNDS + 1):
        next_lo, next_hi, next_spans = [], [], []
        for c0 in range(0, spans.shape[0], max(1, _RESOLUTION_CHUNK // RESOLUTION_SAMPLES)):
            c1 = c0 + max(1, _RESOLUTION_CHUNK // RESOLUTION_SAMPLES)
            l, h, s = lo[c0:c1], hi[c0:c1], spans[c0:c1]
            u = (l[:, None] + (h - l)[:, None] * t[None, :])
            u[:, -1] = h
            flat_s = np.repeat(s, RESOLUTION_SAMPLES)
            speed, C = _speeds(points, weights, knots, p, flat_s, u.reshape(-1))
            speed = speed.reshape(u.shape)
            C = C.reshape(u.shape + (points.shape[1],))
            du = np.diff(u, axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                chord = np.sqrt(((C[:, 1:] - C[:, :-1]) ** 2).sum(axis=2)) / du
            chord = np.where(du > 0, chord, 0.0)
            ulp = np.spacing(np.abs(u))
            ulp_mid = np.maximum(ulp[:, 1:], ulp[:, :-1])
            for values, where_u, scale in ((speed, u, ulp), (chord, u[:, :-1], ulp_mid)):
                prod = values * scale
                if not np.isfinite(prod).all():
                    k = np.unravel_index(int(np.argmax(~np.isfinite(prod))), prod.shape)
                    return math.inf, float(where_u[k])
                k = np.unravel_index(int(np.argmax(prod)), prod.shape)
                if prod[k] > best:
                    best, best_u = float(prod[k]), float(where_u[k])
            peak = (chord > 1.25 * np.maximum(speed[:, 1:], speed[:, :-1])) & (du > np.spacing(np.abs(u[:, 1:])) * 4)
            if peak.any():
                r, j = np.nonzero(peak)
                next_lo.append(u[r, j])
                next_hi.append(u[r, j + 1])
                next_spans.append(s[r])
        if not next_lo:
            break
        lo, hi, spans = np.concatenate(next_lo), np.concatenate(next_hi), np.concatenate(next_spans)
        if lo.shape[0] > 1 << 16:  # bounded work: at most 65 536 intervals a round
            lo, hi, spans = lo[: 1 << 16], hi[: 1 << 16], spans[: 1 << 16]
    return best, best_u


def _check_knots(where: Where, knots: np.ndarray, p: int, n_ctrl: int, raw: list, prefix: str = "curve") -> None:
    need = n_ctrl + p + 1
    if len(knots) != need:
        raise where.fail(f"{prefix}.knots", f"<{len(knots)} values>",
                         f"has the wrong length: {n_ctrl} control points of degree {p} need {need} knots (n_ctrl + degree + 1)")
    for i in range(1, len(knots)):
        if knots[i] < knots[i - 1]:
            raise where.fail(f"{prefix}.knots[{i}]", raw[i], f"is smaller than {prefix}.knots[{i - 1}] = {show(raw[i - 1])}")
    for i in range(1, p + 1):
        if knots[i] != knots[0]:
            raise where.fail(f"{prefix}.knots[{i}]", raw[i],
                             f"differs from {prefix}.knots[0] = {show(raw[0])}: the curve must be clamped (the first degree + 1 = {p + 1} knots equal)")
    last = len(knots) - 1
    for i in range(last - p, last):
        if knots[i] != knots[last]:
            raise where.fail(f"{prefix}.knots[{i}]", raw[i],
                             f"differs from {prefix}.knots[{last}] = {show(raw[last])}: the curve must be clamped (the last degree + 1 = {p + 1} knots equal)")
    if knots[p + 1] == knots[0]:
        raise where.fail(f"{prefix}.knots[{p + 1}]", raw[p + 1],
                         f"repeats the start knot: its multiplicity may be at most degree + 1 = {p + 1}")
    if knots[last - p - 1] == knots[last]:
        raise where.fail(f"{prefix}.knots[{last - p - 1}]", raw[last - p - 1],
                         f"repeats the end knot: its multiplicity may be at most degree + 1 = {p + 1}")
    run = 1
    for i in range(p + 2, last - p):
        run = run + 1 if knots[i] == knots[i - 1] else 1
        if run > p:
            raise where.fail(f"{prefix}.knots[{i}]", raw[i],
                             f"makes an interior knot of multiplicity {run}, more than the degree {p} (the curve would break apart)")
