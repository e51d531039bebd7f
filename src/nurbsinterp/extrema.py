"""Discrete extrema of values sampled per knot span: the search that :meth:`NurbsCurve._refine_extrema
<nurbsinterp.nurbs.NurbsCurve._refine_extrema>` (curvature maxima, bounding box) and the adaptive planner
(minima of the feed limit, maxima of the curvature, minima of the parametric speed) refine by golden section."""
from __future__ import annotations

import numpy as np


def discrete_minima(values, spans, valid=None, finite: bool = True):
    """Sampled local minima of *values* within each knot span: (index, bracket lo, bracket hi), index arrays.

    *values* and *spans* (the knot span of each sample) are flat arrays, sorted by span.  A
    sample no larger than its neighbours in the same span, and smaller than one of them,
    brackets a minimum between those neighbours (inside a run of equal samples only its ends
    are minima: a plateau holds none); at a span end the bracket is the last interval (the
    minimum may lie just inside the span).  Samples not *valid* are no minima and end the
    span for their neighbours, so that no bracket reaches them.  *finite*: leave out
    minima whose value is not finite (-inf); NaN is never a minimum, nor next to one.
    For maxima, pass -values.
    """
    n = values.shape[0]
    idx = np.arange(n)
    ok = np.ones(n, dtype=bool) if valid is None else valid
    has_prev = np.zeros(n, dtype=bool)
    has_next = np.zeros(n, dtype=bool)
    has_prev[1:] = (spans[1:] == spans[:-1]) & ok[:-1]
    has_next[:-1] = (spans[:-1] == spans[1:]) & ok[1:]
    prev = np.where(has_prev, np.roll(values, 1), np.inf)
    nxt = np.where(has_next, np.roll(values, -1), np.inf)
    is_min = (values <= prev) & (values <= nxt) & ((values < prev) | (values < nxt)) & (has_prev | has_next) & ok
    if finite:
        is_min &= np.isfinite(values)
    j = idx[is_min]
    return j, np.where(has_prev[j], j - 1, j), np.where(has_next[j], j + 1, j)
