"""Smoothing: runs of short moves refitted as cubic B-splines within the tolerance, between the reader and the
segments.

CAM samples a smooth surface path by runs of short G1 moves.  Blending each joint with an arc is capped by the
moves' length (a blend takes at most half of each line), so on 1-4 um moves the feed falls to the blends'
tiny radii.  This stage finds the runs (:func:`.fit.split_runs`: cut at corners and long moves) among the
blocks of a batch that may be refitted — straight feed moves, of one feedrate and one tolerance, in blending
mode, with no stop between them — and fits each by :func:`.fit.fit_run`, verified within ``BUDGET`` (0.9) of
the tolerance two-sided; the interpolator's chords keep to the rest (each row's speed cap, below).

*Where a run meets its neighbours.*  A run's first and last moves stay lines, and the curve leaves the first
one's end along its direction and arrives at the last one's start along its: the joints are tangent, and the
corners at the run's ends (a row's turn, a plunge) are blended between lines as before, not passed at the
speed an unblended corner allows.

*Rows.*  A fitted piece becomes one block of kind CURVE for the segment kernel, made of rows that are cubic
Béziers: the piece cut at its knots and at the moves' chord-length boundaries, so that each row lies in one
knot span (a cubic, exactly) and over one programmed move (its block index and its u, the chord-length
fraction of the move, follow linearly).  Each row's caps come from rigorous bounds of its curvature and of
each axis's tangent and curvature-vector components over it (:func:`.segments.curve_bounds`), as an arc's come
from its closed forms: per axis v_i/|τ_i|max, sqrt((1 − β) a_i / |κn_i|max), (a_i − V²|κn_i|max)/|τ_i|max, and
the chord of one tick sagging at most the tolerance left after the fit's verified deviation.

*Windows.*  The stage decides WINDOW blocks at a time, the first WINDOW it holds, whatever the batches the
reader hands on (so that the plan does not depend on them: tested against the program planned whole).  In a
window, a run whose end lies within 3 CORNER_REACH tolerances (or 4 moves) of the window's end may still
grow: it waits for the next window; a run longer than MAX_HOLD moves is cut at MAX_VERTICES along the
tangent its neighbourhood shows, and goes on from there with that tangent.  So a program of 10⁶ moves of
one smooth curve is fitted in bounded pieces.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline

from . import fit
from . import segments as seg

#: vertices of an open run held before it is cut (at fit.MAX_VERTICES from its start)
MAX_HOLD = 2 * fit.MAX_VERTICES
#: where such a run is cut: this many vertices from its start
CUT = fit.MAX_VERTICES
#: blocks decided at a time (a stretch filling a window has MAX_HOLD + 1 vertices: it is cut)
WINDOW = MAX_HOLD
#: a run ending within this many CORNER_REACH tolerances of the last vertex read may still change
MARGIN_REACHES = 3.0
MARGIN_MOVES = 4
#: how far above the sampled maxima a row's bounds may stay (segments.curve_bounds halves it until then)
BOUND_SLACK = 0.01
#: fewest moves refitted (a run's first and last moves stay lines)
MIN_MOVES = 3

NO_CURVES = np.empty((0, seg.NCOL))
# the block arrays (motion.pipeline): their indices
KIND, P0, P1, C, N, SWEEP, RISE, FEED, RAPID, CTRL, TOL, STOP, DWELL, INDEX, UPIECES = range(15)
# Bernstein coefficients of a cubic from its values at w = 0, 1/3, 2/3, 1
_FROM_VALUES = np.linalg.inv(np.array([[math.comb(3, j) * x ** j * (1 - x) ** (3 - j) for j in range(4)]
                                       for x in (0.0, 1 / 3, 2 / 3, 1.0)]))


@dataclass
class SmoothFacts:
    """What smoothing did, for the summary."""

    runs: int = 0  # runs refitted
    moves: int = 0  # programmed moves replaced by curves
    curves: int = 0  # fitted pieces (CURVE blocks)
    rows: int = 0  # their Bézier rows
    worst: float = 0.0  # mm: the largest verified two-sided deviation of a piece from its moves
    kept: int = 0  # runs left as lines and blends (their fit needed pieces of single moves)


def join(a, b):
    """(arrays, curves) of two consecutive parts, b's curve blocks re-indexed into the joined curves."""
    arrays_a, curves_a = a
    arrays_b, curves_b = b
    if arrays_a is None:
        return arrays_b, curves_b
    if curves_b.shape[0] and curves_a.shape[0]:
        arrays_b = list(arrays_b)
        rise = arrays_b[RISE].copy()
        rise[arrays_b[KIND] == seg.CURVE] += curves_a.shape[0]
        arrays_b[RISE] = rise
    arrays = tuple(np.concatenate([x, y]) for x, y in zip(arrays_a, arrays_b))
    curves = curves_b if not curves_a.shape[0] else (curves_a if not curves_b.shape[0]
                                                      else np.concatenate([curves_a, curves_b]))
    return arrays, curves


def tail(arrays, curves, start):
    """(arrays, curves) of blocks start.. only: their curve rows re-indexed from 0."""
    part = tuple(a[start:] for a in arrays)
    mask = part[KIND] == seg.CURVE
    if not mask.any():
        return part, NO_CURVES
    lo = int(part[RISE][mask].min())
    hi = int((part[RISE] + part[UPIECES])[mask].max())
    part = list(part)
    rise = part[RISE].copy()
    rise[mask] -= lo
    part[RISE] = rise
    return tuple(part), curves[lo:hi]


def _unit(v):
    return v / math.sqrt(float(v @ v))


class Smoother:
    """The smoothing stage: :meth:`push` a batch's block arrays, get those now final with runs refitted.

    Parameters: lim (segments' limits vector), enabled (False: blocks pass through), facts (SmoothFacts)."""

    def __init__(self, lim, enabled: bool, facts: SmoothFacts):
        self.lim = lim
        self.enabled = enabled
        self.facts = facts
        self.pending = None  # block arrays held back (the start of a run that may still grow)
        self.tangent = None  # the unit tangent the held blocks' first run continues along (a run cut mid-way)

    def push(self, arrays, curves, last: bool):
        """The blocks of *arrays* (after those held back) that are final, as (arrays, curves); with *last*
        everything.  *curves*: the rows of the CURVE blocks among them (NURBS blocks: motion.nurbs_blocks).

        The blocks are decided WINDOW at a time, whatever the batches they come in: each window is the first
        WINDOW blocks held (or the program's last ones), and what it settles depends on those blocks alone, so
        that a program is smoothed the same whether it is planned whole or read a few blocks at a time."""
        if not self.enabled:
            return arrays, curves
        if self.pending is not None:
            arrays, curves = join(self.pending, (arrays, curves))
            self.pending = None
        done = (None, None)
        while arrays[KIND].shape[0]:
            K = arrays[KIND].shape[0]
            if K < WINDOW and not last:
                break
            final = last and K <= WINDOW
            view = arrays if final else tuple(x[:WINDOW] for x in arrays)
            settled, part = self._window(view, curves, final)
            done = join(done, part)
            arrays, curves = tail(arrays, curves, settled)
            if final:
                break
        if arrays[KIND].shape[0]:
            self.pending = (arrays, curves)
        return done if done[0] is not None else (tuple(x[:0] for x in arrays), NO_CURVES)

    def _window(self, arrays, curves, last):
        """Refit the runs of one window of blocks; returns (the blocks settled, their (arrays, curves))."""
        K = arrays[KIND].shape[0]
        kind, p0, p1, feed, tol = arrays[KIND], arrays[P0], arrays[P1], arrays[FEED], arrays[TOL]
        elig = (kind == seg.LINE) & (arrays[RAPID] == 0) & (arrays[CTRL] == seg.BLEND) & (tol > 0)
        same = np.zeros(K, dtype=bool)
        same[1:] = (elig[1:] & elig[:-1] & (arrays[STOP][1:] == 0) & (arrays[DWELL][1:] == 0)
                    & (feed[1:] == feed[:-1]) & (tol[1:] == tol[:-1]) & np.all(p0[1:] == p1[:-1], axis=1))
        starts = np.flatnonzero(elig & ~same)
        parts = []  # ("copy", lo, hi) and ("curve", block, rows), in order
        done = 0  # blocks before this one are settled
        tangent = self.tangent
        self.tangent = None
        hold = K
        for a in starts:
            e = a + 1
            while e < K and same[e]:
                e += 1
            is_open = e == K and not last
            cont = tangent if a == 0 else None
            settled, held_tangent, out = self._stretch(arrays, a, e, is_open, cont)
            if a > done:
                parts.append(("copy", done, a))
            parts.extend(out)
            done = a + settled
            if is_open:
                hold = done
                self.tangent = held_tangent
                break
        if hold == K and done < K:
            parts.append(("copy", done, K))
        if hold == 0:  # a window of moves of nanometres, no margin reached: settle half of it as lines
            hold = K // 2
            parts = [("copy", 0, hold)]
            self.tangent = None
        return hold, self._assemble(arrays, curves, parts)

    def _stretch(self, arrays, a, e, is_open, cont):
        """Refit the runs of the stretch of blocks a..e−1; returns (blocks settled from a, the tangent the
        held part continues along or None, parts)."""
        p0, p1 = arrays[P0], arrays[P1]
        V = np.concatenate([p0[a:e], p1[e - 1:e]])
        n = V.shape[0]
        tol = float(arrays[TOL][a])
        if n - 1 < MIN_MOVES and not is_open:
            return e - a, None, [("copy", a, e)]
        runs = fit.split_runs(V, tol)
        todo = [(f, l, False) for f, l in runs]
        settled = n - 1
        held_tangent = None
        if is_open:
            s = np.concatenate(([0.0], np.cumsum(np.sqrt(((V[1:] - V[:-1]) ** 2).sum(axis=1)))))
            margin = MARGIN_REACHES * fit.CORNER_REACH * tol

            def final(v):
                return s[-1] - s[v] > margin and n - 1 - v >= MARGIN_MOVES

            todo = [r for r in todo if final(r[1])]
            if todo:
                settled = todo[-1][1]
            elif n > MAX_HOLD:
                f0 = runs[0][0] if runs else n
                c = f0 + CUT
                if c < n and final(c):  # a run longer than the window: cut along its local tangent
                    todo = [(f0, c, True)]
                    settled = c
                    kappa = fit._local_curvature(V, s, tol)
                    held_tangent = fit._local_tangent(V, s, kappa, c, tol)
                else:  # moves no run takes (corners close together, long moves): settle what lies beyond the
                    # margin, up to the start of a run
                    settled = int(np.searchsorted(s, s[-1] - margin, side="left")) - 1
                    settled = max(min(settled, n - 1 - MARGIN_MOVES, f0), 0)
            else:
                settled = 0
        parts = []
        at = 0  # vertex: blocks a + at .. settled
        for f, l, forced in todo:
            continues = cont is not None and f == 0
            fs = f if continues else f + 1
            fe = l if forced else l - 1
            if fe - fs < MIN_MOVES:
                continue
            t_start = cont if continues else _unit(V[f + 1] - V[f])
            t_end = held_tangent if forced else _unit(V[l] - V[l - 1])
            if fs > at:
                parts.append(("copy", a + at, a + fs))
            parts.extend(self._curves(arrays, a, V, fs, fe, t_start, t_end))
            at = fe
        if settled > at:
            parts.append(("copy", a + at, a + settled))
        return settled, held_tangent, parts

    def _curves(self, arrays, a, V, fs, fe, t_start, t_end):
        """The CURVE blocks of the moves fs..fe−1 of the stretch starting at block a."""
        tol = float(arrays[TOL][a])
        feed = float(arrays[FEED][a + fs])
        pieces = fit.fit_run(V[fs:fe + 1], tol, t_start, t_end)
        f = self.facts
        if any(p.last - p.first < 2 for p in pieces):
            # the fit had to split the run down to single moves: they do not sample a smooth curve within the
            # tolerance (noise as large as it, a corner the split missed), and a cubic over one move between
            # prescribed tangents can bend hard; the run stays lines, blended
            f.kept += 1
            return [("copy", a + fs, a + fe)]
        out = []
        for piece in pieces:
            first = fs + piece.first  # vertices of the stretch
            last = fs + piece.last
            rows = self._rows(piece, V[first:last + 1], arrays[INDEX][a + first:a + last], feed, tol)
            ctrl = piece.ctrl
            blk = {
                KIND: seg.CURVE, P0: V[first], P1: V[last], C: _unit(ctrl[1] - ctrl[0]),
                N: _unit(ctrl[-1] - ctrl[-2]), SWEEP: float(rows[:, seg.LEN].sum()), RISE: 0.0,
                FEED: feed, RAPID: 0.0, CTRL: seg.BLEND, TOL: tol, STOP: arrays[STOP][a + first],
                DWELL: arrays[DWELL][a + first], INDEX: arrays[INDEX][a + first], UPIECES: float(rows.shape[0]),
            }
            if not np.all(rows[:, seg.VCAP] > 0.0) or not np.all(np.isfinite(rows[:, seg.ACAP])):
                f.kept += 1  # a cusp (bounds of no use), as above
                return [("copy", a + fs, a + fe)]
            out.append(("curve", blk, rows))
        f.runs += 1
        f.moves += fe - fs
        for _, _, rows in out:
            f.curves += 1
            f.rows += rows.shape[0]
        f.worst = max([f.worst] + [p.deviation for p in pieces])
        return out

    def _rows(self, piece, verts, index, feed, tol):
        """The Bézier rows of one piece over its moves (verts: its vertices; index: their blocks)."""
        chords = np.concatenate(([0.0], np.cumsum(np.sqrt(((verts[1:] - verts[:-1]) ** 2).sum(axis=1)))))
        knots = np.unique(piece.knots)
        x = np.union1d(knots, chords[:-1])
        x = np.append(x[x < knots[-1]], knots[-1])
        # a move's end within a rounding of a knot (1e-12 of the piece) makes no row of its own: the knot stays
        # (a row lies in one knot span), the move's end goes
        close = np.flatnonzero(np.diff(x) <= 1e-12 * max(knots[-1], 1.0))
        if close.size:
            is_knot = np.isin(x, knots)
            drop = np.where(is_knot[close], close + 1, close)
            x = np.delete(x, drop[~is_knot[drop]])
        lo, hi = x[:-1], x[1:]
        R = lo.shape[0]
        spl = BSpline.construct_fast(piece.knots, piece.ctrl, fit.DEGREE)
        w = np.array([0.0, 1 / 3, 2 / 3, 1.0])
        at = lo[:, None] + (hi - lo)[:, None] * w[None, :]
        at[:, -1] = hi
        # each row's values at w = 0, 1/3, 2/3, 1 (a knot at an end is evaluated in the next span: the same point, a
        # cubic spline being continuous; each row is then made to start exactly where the one before ends)
        values = spl(at.ravel()).reshape(R, 4, -1)
        dim = values.shape[2]
        values[0, 0] = verts[0]
        values[-1, -1] = verts[-1]
        values[1:, 0] = values[:-1, -1]  # each row starts exactly where the one before ends
        origin = values[:, :1]
        bez = np.einsum("jk,rkd->rjd", _FROM_VALUES, values - origin) + origin
        bez[:, 0] = values[:, 0]
        bez[:, 3] = values[:, 3]
        rows = np.zeros((R, seg.NCOL))
        for j, col in enumerate((seg.B0, seg.B1, seg.B2, seg.B3)):
            rows[:, col:col + dim] = bez[:, j]
        rows[:, seg.KIND] = seg.CURVE
        move = np.clip(np.searchsorted(chords, 0.5 * (lo + hi), side="right") - 1, 0, len(chords) - 2)
        width = chords[move + 1] - chords[move]
        rows[:, seg.BLOCK] = index[move]
        rows[:, seg.UKIND] = seg.U_CURVE
        rows[:, seg.U0] = (lo - chords[move]) / width
        rows[:, seg.DU] = (hi - lo) / width
        rows[:, seg.NODECAP] = math.inf
        rows[:, seg.JCAP] = math.inf
        finish_rows(rows, self.lim, feed, tol - piece.deviation)
        return rows

    @staticmethod
    def _assemble(arrays, curves, parts):
        """The block arrays of the parts in order, and the curve rows their CURVE blocks refer to (those made here,
        and those of the CURVE blocks copied: in *curves*)."""
        if curves.shape[0]:
            parts = _expand(arrays, curves, parts)
        if all(p[0] == "copy" for p in parts):
            if len(parts) == 1 and parts[0][1] == 0 and parts[0][2] == arrays[KIND].shape[0]:
                return arrays, NO_CURVES
            idx = np.concatenate([np.arange(lo, hi) for _, lo, hi in parts]) if parts else np.zeros(0, np.int64)
            return tuple(x[idx] for x in arrays), NO_CURVES
        pieces = [[] for _ in range(15)]
        curves = []
        nrows = 0
        for p in parts:
            if p[0] == "copy":
                for j in range(15):
                    pieces[j].append(arrays[j][p[1]:p[2]])
            else:
                blk, rows = p[1], p[2]
                blk = dict(blk)
                blk[RISE] = float(nrows)
                for j in range(15):
                    template = arrays[j]
                    pieces[j].append(np.asarray([blk[j]], dtype=template.dtype).reshape((1,) + template.shape[1:]))
                curves.append(rows)
                nrows += rows.shape[0]
        out = tuple(np.concatenate(pj) if pj else arrays[j][:0] for j, pj in enumerate(pieces))
        return out, (np.concatenate(curves) if curves else NO_CURVES)


def _expand(arrays, curves, parts):
    """The parts with each CURVE block a copy part holds made a part of its own ("curve", block, rows)."""
    out = []
    kind = arrays[KIND]
    for p in parts:
        if p[0] != "copy":
            out.append(p)
            continue
        lo, hi = p[1], p[2]
        for j in np.flatnonzero(kind[lo:hi] == seg.CURVE) + lo:
            if j > lo:
                out.append(("copy", lo, j))
            r0 = int(arrays[RISE][j])
            out.append(("curve", {k: arrays[k][j] for k in range(15)}, curves[r0:r0 + int(arrays[UPIECES][j])]))
            lo = j + 1
        if hi > lo:
            out.append(("copy", lo, hi))
    return out


def finish_rows(rows, lim, feed, chord):
    """LEN, VCAP and ACAP of curve rows whose Bézier control points, kind, block and u are set: their lengths, and
    their caps from rigorous bounds of their curvature and tangent (segments.curve_bounds) for the feedrate *feed*,
    the segments' limits vector *lim* and the chord sag allowed (*chord*, mm; with the job's own chord tolerance)."""
    rows[:, seg.LEN] = seg.bezier_lengths(rows)
    bounds = np.empty((rows.shape[0], 7))
    seg.curve_bounds(rows, BOUND_SLACK, bounds)
    curve_caps(rows, lim, bounds[:, 0], bounds[:, 1:4], bounds[:, 4:7], feed, chord)


def curve_caps(rows, lim, kappa, tang, kvec, feed, chord):
    """VCAP and ACAP of curve rows from their bounds, as segments._arc_caps makes an arc's."""
    beta = lim[seg.L_BETA]
    dim = tang.shape[1]
    v = np.full(rows.shape[0], float(feed))
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(dim):
            t = tang[:, i]
            k = kvec[:, i]
            v = np.minimum(v, np.where(t > 0, lim[seg.L_VEL + i] / t, math.inf))
            v = np.minimum(v, np.where(k > 0, np.sqrt((1.0 - beta) * lim[seg.L_ACC + i] / k), math.inf))
        v = np.minimum(v, np.where(kappa > 0, np.sqrt(lim[seg.L_NORMAL] / kappa), math.inf))
        delta = min(lim[seg.L_CHORD], chord)
        rho = np.where(kappa > 0, 1.0 / kappa, math.inf)
        sag_cap = np.where(rho > delta, 2.0 / lim[seg.L_PERIOD] * np.sqrt(np.maximum(2.0 * rho * delta
                                                                                   - delta * delta, 0.0)),
                           2.0 * delta / lim[seg.L_PERIOD])
        v = np.minimum(v, sag_cap)
        a = np.full(rows.shape[0], float(lim[seg.L_ACCEL]))
        for i in range(dim):
            t = tang[:, i]
            centripetal = np.where(v > 0, v * v * kvec[:, i], 0.0)
            a = np.minimum(a, np.where(t > 0, (lim[seg.L_ACC + i] - centripetal) / t, math.inf))
        v[~np.isfinite(kappa)] = 0.0  # a cusp: no bound (the run is then kept as lines)
    rows[:, seg.VCAP] = v
    rows[:, seg.ACAP] = a
