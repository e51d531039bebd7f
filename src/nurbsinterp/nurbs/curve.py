"""The curve object: :class:`NurbsCurve` (validation, evaluation, arc length, curvature, projection
over arrays), built on the kernels of the package's other modules; and the golden-section minimum the
planner's grid uses.
"""
from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from .._jit import njit
from ..errors import SpecError
from ..extrema import discrete_minima
from .kernels import MAX_DERIVATIVE, bezier_table, eval_in_span, eval_many
from .arclength import (ARC_RTOL, MAX_PANELS, MAX_PANEL_DEPTH, PANELS_NOT_FINITE, PANELS_TOO_MANY, arc_length_many,
    build_panels, parameter_at_many)
from .projection import project_many




def _as_params(u):
    arr = np.asarray(u, dtype=float)
    return arr, arr.ndim == 0


class NurbsCurve:
    """A NURBS curve of degree p in 2-D or 3-D.

    Parameters
    ----------
    degree : int, p >= 1 (order = p + 1, the paper's k)
    control_points : array (n+1, dim), mm, dim 2 or 3
    weights : array (n+1,), > 0; default all 1
    knots : array (n+p+2,), non-decreasing, clamped; default clamped uniform on [0, 1]

    The constructor validates with the same rules and messages as job files;
    :meth:`from_spec` takes an already validated :class:`~nurbsinterp.config.CurveSpec`.

    Shape contract: a parameter array of shape (N,) gives points of shape
    (N, dim); a scalar gives (dim,).

    Examples
    --------
    >>> c = NurbsCurve(2, [[0, 0], [0, 50], [100, 50], [100, 0], [100, -50], [0, -50], [0, 0]],
    ...                [1, .5, .5, 1, .5, .5, 1], [0, 0, 0, .25, .5, .5, .75, 1, 1, 1])
    >>> round(c.length, 9)
    314.159265359
    """

    def __init__(self, degree, control_points, weights=None, knots=None):
        from ..config import Where, validate_curve

        def plain(value):  # lists as they are, so that validation names what is wrong in them
            return value.tolist() if isinstance(value, np.ndarray) else (list(value) if isinstance(value, tuple) else value)

        raw = {"degree": degree, "control_points": [plain(cp) for cp in plain(control_points)]
               if isinstance(plain(control_points), list) else control_points}
        if weights is not None:
            raw["weights"] = plain(weights)
        if knots is not None:
            raw["knots"] = plain(knots)
        spec = validate_curve(raw, Where("NurbsCurve"))
        self._init(spec.degree, spec.control_points, spec.weights, spec.knots)

    @classmethod
    def from_spec(cls, spec) -> "NurbsCurve":
        obj = cls.__new__(cls)
        obj._init(spec.degree, spec.control_points, spec.weights, spec.knots)
        return obj

    def _init(self, degree, control_points, weights, knots):
        cps = np.array(control_points, dtype=float)
        w = np.array(weights, dtype=float)
        self.degree = int(degree)
        self.knots = np.array(knots, dtype=float)
        self.control_points = cps
        self.weights = w
        self.Pw = np.ascontiguousarray(np.column_stack([cps * w[:, None], w]))
        self.n = cps.shape[0] - 1
        self.bezier = bezier_table(self.knots, self.Pw, self.degree, self.n)
        for arr in (self.knots, self.control_points, self.weights, self.Pw, self.bezier):
            arr.setflags(write=False)

    # -- basic facts
    @property
    def dim(self) -> int:
        return self.control_points.shape[1]

    @property
    def domain(self) -> tuple[float, float]:
        return float(self.knots[self.degree]), float(self.knots[self.n + 1])

    @property
    def kernel_args(self):
        """(U, B, p, n): the plain-array form every kernel takes (B: the Bezier table, see :func:`bezier_table`)."""
        return self.knots, self.bezier, self.degree, self.n

    def span_ranges(self):
        """[(span index, start, end)] of the non-empty knot spans."""
        U, p, n = self.knots, self.degree, self.n
        return [(i, float(U[i]), float(U[i + 1])) for i in range(p, n + 1) if U[i + 1] > U[i]]

    # -- evaluation
    def derivatives(self, u, order: int = 1) -> np.ndarray:
        """Point and derivatives up to *order*: shape (N, order+1, dim), or (order+1, dim) for scalar u."""
        if not 0 <= order <= MAX_DERIVATIVE:
            raise ValueError(f"derivative order {order} is not supported (0 .. {MAX_DERIVATIVE})")
        arr, scalar = _as_params(u)
        flat = np.ascontiguousarray(arr.reshape(-1))
        self._check_domain(flat)
        out = np.empty((flat.shape[0], order + 1, self.dim))
        eval_many(*self.kernel_args, flat, order, out)
        return out[0] if scalar else out.reshape(arr.shape + (order + 1, self.dim))

    def evaluate(self, u) -> np.ndarray:
        """Points C(u): (N, dim) for u of shape (N,), (dim,) for a scalar."""
        d = self.derivatives(u, 0)
        return d[..., 0, :]

    __call__ = evaluate

    def _check_domain(self, flat):
        a, b = self.domain
        if flat.size and not (np.all(flat >= a) and np.all(flat <= b)):
            bad = flat[~((flat >= a) & (flat <= b))][0]
            raise ValueError(f"parameter u = {bad!r} is outside the domain [{a!r}, {b!r}]")

    def speed(self, u) -> np.ndarray:
        """Parametric speed |C'(u)|, mm per unit of u."""
        return np.linalg.norm(self.derivatives(u, 1)[..., 1, :], axis=-1)

    def curvature(self, u) -> np.ndarray:
        """Curvature (1/mm); inf where the parametric speed is zero."""
        d = self.derivatives(u, 2)
        return _curvature_table(d.reshape(-1, 3, self.dim), self.dim).reshape(d.shape[:-2]) if d.ndim > 2 \
            else float(_curvature_table(d[None], self.dim)[0])

    # -- arc length
    @cached_property
    def _panel_build(self):
        """(starts, spans, cum, status, floor): :func:`build_panels` as it returned, unchecked (see :attr:`panels`)."""
        # rounding in the control points leaves about p eps |P| (times the weight ratio) of noise
        # in each panel's length; below that the test could never pass (a rational curve shrunk
        # to one point has a length of pure noise, and would be bisected 2^40 times)
        floor = 4.0 * self.degree * np.finfo(float).eps * float(np.abs(self.control_points).max()) \
            * float(self.weights.max() / self.weights.min())
        return (*build_panels(*self.kernel_args, ARC_RTOL, floor, MAX_PANEL_DEPTH, MAX_PANELS), floor)

    @cached_property
    def length_noise(self) -> float:
        """The rounding noise of :attr:`length` (mm): the panels' floor times their number."""
        _starts, spans, _cum, _status, floor = self._panel_build
        return floor * max(1, spans.shape[0])

    @cached_property
    def panels(self):
        """(starts, spans, cum): the arc-length table (see :func:`build_panels`)."""
        starts, spans, cum, status, _floor = self._panel_build
        if status == PANELS_NOT_FINITE:
            raise SpecError(f"curve: the parametric speed overflows near u = {starts[0]!r} (coordinates, weights "
                            "or knot spans too extreme); the arc length cannot be computed")
        if status == PANELS_TOO_MANY:
            raise SpecError(f"curve: the arc length needs more than {MAX_PANELS} Gauss panels to converge (near "
                            f"u = {starts[0]!r}): the speed varies too wildly (extreme weights or knot spans)")
        for arr in (starts, spans, cum):
            arr.setflags(write=False)
        return starts, spans, cum

    @property
    def length(self) -> float:
        """Total arc length, mm."""
        return float(self.panels[2][-1])

    @property
    def resolvable(self) -> bool:
        """Whether the length stands above the rounding noise of the control points (:attr:`length_noise`, mm)."""
        return self.length > self.length_noise

    def arc_length_at(self, u) -> np.ndarray:
        """s(u): arc length from the domain start to u, mm."""
        arr, scalar = _as_params(u)
        flat = np.ascontiguousarray(arr.reshape(-1))
        self._check_domain(flat)
        out = np.empty(flat.shape[0])
        arc_length_many(self.knots, self.bezier, self.degree, *self.panels, flat, out)
        return float(out[0]) if scalar else out.reshape(arr.shape)

    def arc_length(self, u0=None, u1=None):
        """Arc length from u0 to u1 (default: the whole domain), mm."""
        a, b = self.domain
        return self.arc_length_at(b if u1 is None else u1) - self.arc_length_at(a if u0 is None else u0)

    def parameter_at(self, s) -> np.ndarray:
        """The inverse of :meth:`arc_length_at`: u with s(u) = s (s clamped to [0, L])."""
        arr, scalar = _as_params(s)
        flat = np.ascontiguousarray(arr.reshape(-1))
        if not np.all(np.isfinite(flat)):
            raise ValueError("arc length must be finite")
        out = np.empty(flat.shape[0])
        parameter_at_many(self.knots, self.bezier, self.degree, *self.panels, flat, out)
        return float(out[0]) if scalar else out.reshape(arr.shape)

    # -- projection
    def closest_point(self, points, seeds=None, samples: int = 16):
        """Closest point on the curve: returns (u, distance).

        points : (N, dim) or (dim,).  seeds : optional (N,) parameters near the
        answer (e.g. the commanded u of each servo tick); without seeds every
        knot span is searched (*samples* per span, then Newton).
        """
        q = np.asarray(points, dtype=float)
        scalar = q.ndim == 1
        q2 = np.ascontiguousarray(q.reshape(-1, self.dim))
        if seeds is None:
            s = np.zeros(q2.shape[0])
        else:
            s = np.ascontiguousarray(np.broadcast_to(np.asarray(seeds, dtype=float), (q2.shape[0],)))
            a, b = self.domain
            s = np.clip(s, a, b)
        out_u = np.empty(q2.shape[0])
        out_d = np.empty(q2.shape[0])
        project_many(*self.kernel_args, q2, s, seeds is not None, samples, out_u, out_d)
        if scalar:
            return float(out_u[0]), float(out_d[0])
        return out_u, out_d

    # -- shape facts (one-time, for `info` and planning)
    def _in_span(self, us, spans, order):
        out = np.empty((us.shape[0], order + 1, self.dim))
        eval_in_span(self.knots, self.bezier, self.degree, np.ascontiguousarray(us), np.ascontiguousarray(spans), order, out)
        return out

    def _samples(self, per_span: int, order: int):
        """(span ranges, span index per sample, u per sample, derivative table) on a grid of
        per_span + 1 samples in every non-empty knot span, all spans at once."""
        ranges = np.array(self.span_ranges(), dtype=float).reshape(-1, 3)
        spans = np.repeat(ranges[:, :1].astype(np.int64), per_span + 1, axis=1)
        us = ranges[:, 1:2] + (ranges[:, 2:3] - ranges[:, 1:2]) * np.linspace(0.0, 1.0, per_span + 1)
        us[:, -1] = ranges[:, 2]
        return ranges, spans, us, self._in_span(us.ravel(), spans.ravel(), order)

    def _refine_extrema(self, func, samples, order: int, sign: float, hull=None):
        """Maxima of sign*func(d) per knot span: the samples, then golden section, all spans at once.

        *func* maps a derivative table (N, order + 1, dim) to values (N,); *samples*
        come from :meth:`_samples`.  Returns a list of (value, u) for every sampled
        local maximum (span ends included; inside a run of equal samples only its
        ends), refined within one sample either side.  *hull*: optional coordinate
        index; then only the spans whose Bezier control points reach beyond the
        largest sample are refined (a span lies in their convex hull), since the
        caller wants the largest value only.
        """
        ranges, spans, us, table = samples
        vals = sign * func(table)
        flat_u = us.ravel()
        # a straight line's curvature or a constant coordinate is one plateau: its inside holds no peak
        k, lo, hi = discrete_minima(-vals, spans.ravel(), finite=False)
        row = k // us.shape[1]
        best_v, best_u = vals[k], flat_u[k]
        fine = np.isfinite(best_v)
        if hull is not None and fine.any():
            bz = self.bezier[ranges[:, 0].astype(np.int64), 0]  # (spans, p + 1, dim + 1), homogeneous
            reach = (sign * bz[:, :, hull] / bz[:, :, -1]).max(axis=1)
            fine &= reach[row] > best_v[fine].max()
        if fine.any():
            span = spans.ravel()[k[fine]]

            def neg(x):
                return -sign * func(self._in_span(x, span, order))

            u = golden_minimum(neg, flat_u[lo[fine]], flat_u[hi[fine]])
            v = -neg(u)
            better = v > best_v[fine]
            best_v[fine] = np.where(better, v, best_v[fine])
            best_u[fine] = np.where(better, u, best_u[fine])
        return [(sign * float(v), float(u)) for v, u in zip(best_v, best_u)]

    def curvature_maxima(self, per_span: int = 32):
        """Local curvature maxima per knot span as (curvature, u), span ends included.

        Sampling alone can miss a sharp peak between samples; each sampled local
        maximum is refined by golden section inside its bracket.
        """
        return self._refine_extrema(lambda d: _curvature_table(d, self.dim), self._samples(per_span, 2), 2, 1.0)

    def min_radius(self):
        """(minimum radius of curvature in mm, u where it occurs)."""
        kappa, u = max(self.curvature_maxima(), key=lambda t: t[0])
        return (1.0 / kappa if kappa > 0 else math.inf), u

    def bounding_box(self, per_span: int = 32):
        """(lower corner, upper corner) of the curve itself (not of its control polygon)."""
        samples = self._samples(per_span, 0)
        lo = np.empty(self.dim)
        hi = np.empty(self.dim)
        for c in range(self.dim):
            def coord(d, c=c):
                return d[:, 0, c]
            hi[c] = max(v for v, _ in self._refine_extrema(coord, samples, 0, 1.0, hull=c))
            lo[c] = min(v for v, _ in self._refine_extrema(coord, samples, 0, -1.0, hull=c))
        return lo, hi


GOLDEN_ITERATIONS = 60  # shrinks a bracket by 0.618^60 = 3e-13


_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


@njit(cache=True)
def _golden_shrink(a, b, c, e, fc, fe, left, new):
    """One step of golden section on every bracket [a, b], as nurbs.golden_minimum takes it: keep the side of
    the smaller of f(c), f(e) (the left one on a tie), and the next point to try (into new)."""
    for i in range(a.shape[0]):
        keep_left = fc[i] <= fe[i]
        left[i] = keep_left
        if keep_left:
            b[i] = e[i]
            new[i] = b[i] - _GOLDEN * (b[i] - a[i])
        else:
            a[i] = c[i]
            new[i] = a[i] + _GOLDEN * (b[i] - a[i])


@njit(cache=True)
def _golden_keep(c, e, fc, fe, new, fn, left):
    """The two inner points after a step: the new one and the better of the old ones, in order."""
    for i in range(c.shape[0]):
        if left[i]:
            e[i] = c[i]
            fe[i] = fc[i]
            c[i] = new[i]
            fc[i] = fn[i]
        else:
            c[i] = e[i]
            fc[i] = fe[i]
            e[i] = new[i]
            fe[i] = fn[i]


def golden_minimum(f, lo, hi, iterations: int = GOLDEN_ITERATIONS):
    """Minimum of f (vectorised over the brackets [lo, hi]) by golden section.

    One call of f per iteration for all brackets at once, so thousands of
    brackets cost what one does in Python overhead; each step's updates are two
    kernels (the planner runs it on a few brackets per knot span).
    """
    a = np.array(lo, dtype=float)
    b = np.array(hi, dtype=float)
    c = b - _GOLDEN * (b - a)
    e = a + _GOLDEN * (b - a)
    fc = np.array(f(c), dtype=float)  # copies: the kernels update them in place
    fe = np.array(f(e), dtype=float)
    left = np.empty(a.shape, dtype=np.bool_)
    new = np.empty(a.shape)
    for _ in range(iterations):
        _golden_shrink(a, b, c, e, fc, fe, left, new)
        _golden_keep(c, e, fc, fe, new, np.ascontiguousarray(f(new), dtype=float), left)
    return np.where(fc <= fe, c, e)


def _curvature_table(d, dim):
    d1, d2 = d[:, 1, :], d[:, 2, :]
    if dim == 2:
        cross = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    else:
        cross = np.linalg.norm(np.cross(d1, d2), axis=-1)
    sp = np.linalg.norm(d1, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(sp > 0, cross / np.where(sp > 0, sp, 1.0) ** 3, np.inf)
