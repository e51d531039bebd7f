"""NURBS geometry: evaluation, derivatives, arc length, curvature, projection.

The package, a module a seam: :mod:`.kernels` (evaluation), :mod:`.arclength`, :mod:`.projection`
(used by the measures only), :mod:`.curve` (:class:`NurbsCurve`).  Every name is importable from here.

Conventions
-----------
Degree p (order = p + 1, the paper's k); control points V_0..V_n; knots
U_0..U_{n+p+1}; parameter domain [U_p, U_{n+1}].  Control points are stored
homogeneous, ``B[i] = (W_i V_i, W_i)``, so the rational derivatives are one
quotient rule (Piegl & Tiller, A4.2).

Derivatives are right-sided: at an interior knot u = U_i the polynomial of the
span [U_i, U_{i+1}) is used, so a knot of multiplicity p (the paper's circle
has one at 0.5) gives the exact one-sided derivative the interpolator needs
when it steps forward.  The domain end U_{n+1} belongs to the last span.

Every per-point routine is a numba kernel working on plain arrays with a
preallocated workspace, so that the per-tick path does no allocation and no
Python-level work; the vectorised methods of :class:`NurbsCurve` loop the same
kernels over arrays.
"""
from __future__ import annotations

from .kernels import (find_span, find_span_from, MAX_DERIVATIVE, make_work, bezier_table, _store_segment, curve_ders,
    ders_fast, ders_fast_called, norm_row, dot_rows, speed_at, eval_many, eval_in_span)
from .arclength import (GL_NODES, GL_WEIGHTS, STEP_NODES, STEP_WEIGHTS, STEP_FRACTION, ARC_RTOL, MAX_PANEL_DEPTH,
    MAX_PANELS, PANELS_OK, PANELS_NOT_FINITE, PANELS_TOO_MANY, step_length_fast, gauss_length, build_panels, _grow,
    arc_length_to, step_length_mid, step_length, parameter_at, arc_length_many, parameter_at_many)
from .projection import (_distance2, _newton_project, _newton_project_fast, NEWTON_FAILED, NEWTON_CONVERGED,
    NEWTON_AT_END, newton_foot, newton_foot_called, span_near, project_window, _box_distance2, BB_DEPTH, BB_RTOL, BB_ATOL, make_search,
    _binom, _split_bezier, _set_piece, _may_be_closer, project_interval, project_global, _window_end,
    project_arc_window, CONVEX_LIMIT, make_certificate, _bezier_split, curvature_bound, CURVATURE_SPLITS,
    CURVATURE_DEPTH, panel_curvature, _unit_tangent, joint_turn, panel_at, fill_certificate, window_bounds,
    is_convex, panel_window, panel_window_called, _lower_panel_end, _upper_panel_end, project_seeded, project_many)
from .curve import (_as_params, NurbsCurve, GOLDEN_ITERATIONS, _GOLDEN, _golden_shrink, _golden_keep, golden_minimum,
    _curvature_table)

__all__ = [  # every name of the old single module, importable from here as before
    "find_span", "find_span_from", "MAX_DERIVATIVE", "make_work", "bezier_table", "_store_segment", "curve_ders",
    "ders_fast", "ders_fast_called", "norm_row", "dot_rows", "speed_at", "eval_many", "eval_in_span", "GL_NODES", "GL_WEIGHTS",
    "STEP_NODES", "STEP_WEIGHTS", "STEP_FRACTION", "ARC_RTOL", "MAX_PANEL_DEPTH", "MAX_PANELS", "PANELS_OK",
    "PANELS_NOT_FINITE", "PANELS_TOO_MANY", "step_length_fast", "gauss_length", "build_panels", "_grow",
    "arc_length_to", "step_length_mid", "step_length", "parameter_at", "arc_length_many", "parameter_at_many",
    "_distance2", "_newton_project", "_newton_project_fast", "NEWTON_FAILED", "NEWTON_CONVERGED", "NEWTON_AT_END",
    "newton_foot", "newton_foot_called", "span_near", "project_window", "_box_distance2", "BB_DEPTH", "BB_RTOL", "BB_ATOL", "make_search",
    "_binom", "_split_bezier", "_set_piece", "_may_be_closer", "project_interval", "project_global", "_window_end",
    "project_arc_window", "CONVEX_LIMIT", "make_certificate", "_bezier_split", "curvature_bound", "CURVATURE_SPLITS",
    "CURVATURE_DEPTH", "panel_curvature", "_unit_tangent", "joint_turn", "panel_at", "fill_certificate",
    "window_bounds", "is_convex", "panel_window", "panel_window_called", "_lower_panel_end", "_upper_panel_end", "project_seeded",
    "project_many", "_as_params", "NurbsCurve", "GOLDEN_ITERATIONS", "_GOLDEN", "_golden_shrink", "_golden_keep",
    "golden_minimum", "_curvature_table",
]
