"""Blocks as segments: each block its own piece of path, each corner blended from its two neighbours only.

A segment is a line or a circular (or helical) arc, parametrised by its own arc
length, with the caps the planner needs: the feedrate it may be passed at
(VCAP), the tangential acceleration it leaves (ACAP), and the feedrate at its
start node (NODECAP: a joint's own cap, 0 at a stop).  Segments are rows of a
float64 table (columns below), built for a batch of blocks at a time by one
kernel, so that a program is never held whole: the batch's last block waits
for the next batch, whose first joint decides its end.

Joints
------
At the joint of block i and block i + 1 (unit tangents τ1 at i's end, τ2 at
i + 1's start, turning by θ = acos(τ1·τ2)), in this order:

- a *stop* (the tool at rest) where the program asks for one (block i + 1's
  ``stop`` or ``dwell``: M0, M1, M6, M60, G4 ...), where block i is in exact-stop
  mode (G61.1), and at a reversal (θ >= REVERSAL: a retract then a plunge), which
  nothing can pass at speed;
- on the *exact path* (block i in exact-path mode, G61, or with no tolerance: a
  program that states no G64 P, or tolerance 0), never a blend: the joint is passed
  unblended (below) at its jump cap, which is 0 -- a stop -- where the jump would
  take more than the axes have over the two ticks around it (a right angle at a
  few mm/s): LinuxCNC's exact-path mode, which slows at a kink as much as the
  acceleration needs and stops where it must;
- otherwise, between two lines, a *blend*: the circular arc tangent to both lines
  at distance d from the corner.  Its radius is R = d / tan(θ/2) and every point of
  it lies within e = d·tan(θ/4) of the corner's two legs, and every point of those
  legs within e of it (the corner itself is the farthest: e exactly), so
  d = δ / tan(θ/4) for the tolerance δ, at most half of either line (a line may
  give half its length to the blend at each end).  A circle, not a curve of
  varying curvature: on a polyline sampled from a smooth curve the blends of
  consecutive joints meet (or nearly) with nearly the radius of the curve, so the
  curvature does not chatter from blend to line to blend; and its caps are exact.
- or, under the axes' jerk limits, a *rest* on the corner, exactly on the programmed
  path, where crossing the blend at the speed the jerk leaves it would take longer
  than stopping and starting again (see _blend_crawls; STOP = CORNER_REST);
- or, where a blend would pass slower than the joint itself could be passed (a tiny
  turn between tiny moves), or the joint involves an arc, the joint is passed *unblended*, its commands exactly on
  the programmed path, at the speed whose jump of velocity direction stays within
  a share γ of each axis' acceleration over one tick: the tick that straddles the
  joint has a second difference of at most V·|Δτ_i|·T, so
  V <= γ·a_i·T / |Δτ_i| (Δτ = τ2 − τ1), less what the tangential acceleration can
  add over the two ticks around it.  The lines beside such a joint keep 1 − γ of
  their acceleration for the tangential part, so that the sum stays within a_i,
  and a segment between two such joints is never crossed in less than 2.5 ticks
  (its cap L / 2.5T), so that no three ticks straddle two of them.

Caps of a segment (per axis i: v_i, a_i the axis limits; F the block's feedrate)
------------------------------------------------------------------------------
line (unit direction τ): V <= min(F, v_i / |τ_i|); |A| <= a_i / |τ_i|.
arc of radius R (curvature κ = R/ℓ² for a helix of lead h per radian, ℓ² = R² + h²):
max |τ_i| and max |n_i| over the sweep in closed form (A cos θ + B sin θ + C);
V <= sqrt((1 − β)·a_i / (κ max|n_i|)), so that the centripetal part takes at most
1 − β of each axis' budget; |A| <= (a_i − V_cap² κ max|n_i|) / max|τ_i|
(>= β a_i / max|τ_i|), as the adaptive planner splits it; and V <= sqrt(A_n/κ)
(max_normal_accel), V <= (2/T)·sqrt(2ρδ_c − δ_c²) (chord tolerance, ρ >= δ_c).
The path's tangential max_accel caps every |A|.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit

# columns of a segment row
S0, LEN, KIND, BLOCK = 0, 1, 2, 3
P = 4  # 4:7 the segment's start point
D = 7  # 7:10 a line's unit direction; an arc's e1 (from the centre to its start)
E = 10  # 10:13 an arc's e2 (the tangent at its start, in its plane)
NRM = 13  # 13:16 an arc's axis (unit)
RADIUS, SWEEP, RISE = 16, 17, 18
UKIND, U0, DU, UANG = 19, 20, 21, 22  # how the block's own parameter u follows s (see segment_u)
VCAP, ACAP, NODECAP, STOP, DWELL, RAPID = 23, 24, 25, 26, 27, 28
JCAP = 29  # the jerk the planner may take along the segment (motion.jerk; inf: none of its own)
NCOL = 30

LINE, ARC, CURVE = 0, 1, 2
U_LINEAR, U_ARC, U_BLEND_IN, U_BLEND_OUT, U_CURVE = 0, 1, 2, 3, 4
# a CURVE row (a cubic Bézier piece of a run of short moves refitted by motion.smooth): its control points B0..B3
# at P, D, E, NRM (the columns a line or an arc uses for its frame); u = U0 + DU·w of its Bézier parameter w
B0, B1, B2, B3 = P, D, E, NRM

# block arrays' control mode codes (config.path.CONTROL_MODES order)
BLEND, EXACT_PATH, EXACT_STOP = 0, 1, 2

# the limits vector (see limits.MotionLimits.vector)
L_PERIOD, L_BETA, L_GAMMA, L_ACCEL, L_NORMAL, L_CHORD = 0, 1, 2, 3, 4, 5
L_VEL = 6  # 6:9 per-axis max velocity (inf: none)
L_ACC = 9  # 9:12 per-axis max acceleration (inf: none)
L_BLEND_BETA = 12  # β of a corner blend (see limits.BLEND_TANGENTIAL_SHARE)
L_JERK = 13  # 13:16 per-axis max jerk (inf: none; motion.jerk holds it)
L_RAMP_JERK = 16  # the jerk the ramps take along the path (limits.MotionLimits.tangential_jerk)
L_JUMP_SHARE, L_SPEED_SHARE = 17, 18  # the shares of an axis' jerk a joint's jump and a row's V³ x_sss part take
NLIM = 19

#: the STOP column of a corner taken at rest because crossing its blend would take longer (see build_segments);
#: a program's stop is 1 (and wins where the two meet at one node)
CORNER_REST = 0.5
STEP_JUMP = 0.75  # the largest third difference of an acceleration step of 1 over one tick, times T (motion.jerk)
REVERSAL = math.radians(179.0)  # a joint turning by this much or more is a stop: a retract then a plunge
EXACT_PATH_KINK = 1e-6  # rad: a joint that turns by at most this is tangent (rounding): no tolerance needed to pass it
MIN_LENGTH = 1e-9  # mm: a block shorter than this is no motion (its stop passes to the next)
#: mm: a blend no larger than this is none (the joint is passed unblended): below some 1e-162 mm its radius
#: squared underflows, and nothing of a machine's is that small
MIN_BLEND = 1e-15
STRADDLE_TICKS = 2.5  # a segment between two unblended joints takes at least this many ticks


@njit(cache=True)
def _unit(v):
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return v / n, n


@njit(cache=True)
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def trig_absmax(A, B, C, phi):
    """max |A cos θ + B sin θ + C| over θ in [0, phi] (phi <= 2π): the ends and the stationary points inside."""
    best = max(abs(A + C), abs(A * math.cos(phi) + B * math.sin(phi) + C))
    if A != 0.0 or B != 0.0:
        th = math.atan2(B, A)
        for k in range(-1, 4):
            t = th + k * math.pi
            if 0.0 < t < phi:
                best = max(best, abs(A * math.cos(t) + B * math.sin(t) + C))
    return best


@njit(cache=True)
def _line_caps(row, feed, lim):
    """VCAP and ACAP of a line row (its direction at D)."""
    v = feed
    a = lim[L_ACCEL]
    for i in range(3):
        t = abs(row[D + i])
        if t > 0.0:
            v = min(v, lim[L_VEL + i] / t)
            a = min(a, lim[L_ACC + i] / t)
    row[VCAP] = v
    row[ACAP] = a


@njit(cache=True)
def _arc_caps(row, feed, lim, chord=math.inf, beta=-1.0):
    """VCAP and ACAP of an arc row (see the module's docstring); *chord*: the largest sag of a tick's chord
    (the block's tolerance, for an arc of the program), besides the chord tolerance of the limits."""
    R = row[RADIUS]
    phi = row[SWEEP]
    h = row[RISE] / phi  # lead per radian
    ell = math.sqrt(R * R + h * h)
    kappa = R / (ell * ell)
    v = feed
    if beta < 0.0:
        beta = lim[L_BETA]
    tmax = np.empty(3)
    nmax = np.empty(3)
    for i in range(3):
        # τ_i(θ) = (R(−sin θ e1_i + cos θ e2_i) + h n_i) / ℓ ;  n_i(θ) = −(cos θ e1_i + sin θ e2_i)
        tmax[i] = trig_absmax(R * row[E + i] / ell, -R * row[D + i] / ell, h * row[NRM + i] / ell, phi)
        nmax[i] = trig_absmax(-row[D + i], -row[E + i], 0.0, phi)
        if tmax[i] > 0.0:
            v = min(v, lim[L_VEL + i] / tmax[i])
        if nmax[i] > 0.0:
            v = min(v, math.sqrt((1.0 - beta) * lim[L_ACC + i] / (kappa * nmax[i])))
    v = min(v, math.sqrt(lim[L_NORMAL] / kappa))
    delta = min(lim[L_CHORD], chord)
    rho = 1.0 / kappa
    if delta < math.inf:
        if rho > delta:
            v = min(v, 2.0 / lim[L_PERIOD] * math.sqrt(2.0 * rho * delta - delta * delta))
        else:
            v = min(v, 2.0 * delta / lim[L_PERIOD])
    a = lim[L_ACCEL]
    for i in range(3):
        if tmax[i] > 0.0:
            a = min(a, (lim[L_ACC + i] - v * v * kappa * nmax[i]) / tmax[i])
    row[VCAP] = v
    row[ACAP] = a


@njit(cache=True)
def _arc_frame(P0, C, N):
    """(e1, e2, R) of an arc from its start, centre and axis: e1 from the centre to the start."""
    r = P0 - C
    r = r - (r[0] * N[0] + r[1] * N[1] + r[2] * N[2]) * N  # the helix's start circle
    e1, R = _unit(r)
    return e1, _cross(N, e1), R


@njit(cache=True)
def _arc_tangent(e1, e2, N, R, phi, rise, th):
    h = rise / phi
    t = R * (-math.sin(th) * e1 + math.cos(th) * e2) + h * N
    return _unit(t)[0]


@njit(cache=True)
def block_tangents(kind, P0, P1, C, N, sweep, rise):
    """(unit tangent at the start, at the end, length) of one block."""
    if kind == LINE:
        d, L = _unit(P1 - P0)
        return d, d, L
    e1, e2, R = _arc_frame(P0, C, N)
    h = rise / sweep
    L = math.sqrt(R * R + h * h) * sweep
    return (_arc_tangent(e1, e2, N, R, sweep, rise, 0.0), _arc_tangent(e1, e2, N, R, sweep, rise, sweep), L)


@njit(cache=True)
def _put_line(out, m, start, t, trim_in, length, block, u0, du, feed, rapid, lim):
    """A line row: from start + trim_in·t along the unit direction t for *length* mm."""
    row = out[m]
    row[:] = 0.0
    row[LEN] = length
    row[KIND] = LINE
    row[BLOCK] = block
    for i in range(3):
        row[P + i] = start[i] + trim_in * t[i] if trim_in != 0.0 else start[i]
        row[D + i] = t[i]
    row[UKIND] = U_LINEAR
    row[U0] = u0
    row[DU] = du
    row[NODECAP] = math.inf
    row[JCAP] = math.inf
    row[RAPID] = rapid
    _line_caps(row, feed, lim)
    return m + 1


@njit(cache=True)
def _put_arc(out, m, start, e1, e2, N, R, phi, rise, block, ukind, u0, du, uang, feed, rapid, lim, chord=math.inf):
    row = out[m]
    row[:] = 0.0
    h = rise / phi
    row[LEN] = math.sqrt(R * R + h * h) * phi
    row[KIND] = ARC
    row[BLOCK] = block
    row[P:P + 3] = start
    row[D:D + 3] = e1
    row[E:E + 3] = e2
    row[NRM:NRM + 3] = N
    row[RADIUS] = R
    row[SWEEP] = phi
    row[RISE] = rise
    row[UKIND] = ukind
    row[U0] = u0
    row[DU] = du
    row[UANG] = uang
    row[NODECAP] = math.inf
    row[JCAP] = math.inf
    row[RAPID] = rapid
    _arc_caps(row, feed, lim, chord, -1.0)  # (every argument given: no omitted variant)
    return m + 1


@njit(cache=True)
def _jump_cap(t1, t2, lim, acap_near):
    """The feedrate an unblended joint may be passed at (see the module's docstring)."""
    T = lim[L_PERIOD]
    gamma = lim[L_GAMMA]
    v = math.inf
    total = 0.0
    for i in range(3):
        dt = abs(t2[i] - t1[i])
        total += dt * dt
        if dt > 0.0:
            # (V + 2T·A_t) |Δτ_i| / T <= γ a_i: the speed reached within the two ticks around the joint
            v = min(v, gamma * lim[L_ACC + i] * T / dt - 2.0 * T * acap_near)
    if total > 0.0:
        v = min(v, gamma * lim[L_ACCEL] * T / math.sqrt(total) - 2.0 * T * acap_near)
    return max(v, 0.0)


@njit(cache=True)
def _tangents(kind, P0, P1, C, N, sweep, rise, ts, te, L):
    """Unit tangents at each block's start and end, and its length, into ts, te (K, 3) and L (K,)."""
    for b in range(kind.shape[0]):
        if kind[b] == LINE:
            d0 = P1[b, 0] - P0[b, 0]
            d1 = P1[b, 1] - P0[b, 1]
            d2 = P1[b, 2] - P0[b, 2]
            n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            ts[b, 0] = te[b, 0] = d0 / n
            ts[b, 1] = te[b, 1] = d1 / n
            ts[b, 2] = te[b, 2] = d2 / n
            L[b] = n
        elif kind[b] == CURVE:  # a refitted run: its end tangents in C and N, its length in sweep
            ts[b] = C[b]
            te[b] = N[b]
            L[b] = sweep[b]
        else:
            a, z, length = block_tangents(kind[b], P0[b], P1[b], C[b], N[b], sweep[b], rise[b])
            ts[b] = a
            te[b] = z
            L[b] = length


@njit(cache=True)
def _turn(t1, t2, inward):
    """The angle between unit tangents t1 and t2, and into *inward* the unit normal towards t2 in their plane.

    θ = 2 atan2(|t2 − t1|, |t2 + t1|), not acos(t1·t2): acos near 1 loses √ε of the angle (a turn of 1.7e-7
    rad came out 0.4 % off, and the blend built on it missed the next line's start by 1e-10 mm, a spike of
    1e-4 mm/s² in the commands' second difference); the normal from t2 − t1 less its part along t1."""
    d2 = 0.0
    s2 = 0.0
    along = 0.0
    for i in range(3):
        d = t2[i] - t1[i]
        d2 += d * d
        s2 += (t2[i] + t1[i]) ** 2
        along += d * t1[i]
    n2 = 0.0
    for i in range(3):
        inward[i] = t2[i] - t1[i] - along * t1[i]
        n2 += inward[i] * inward[i]
    if n2 > 0.0:
        n = math.sqrt(n2)
        for i in range(3):
            inward[i] /= n
    return 2.0 * math.atan2(math.sqrt(d2), math.sqrt(s2))


@njit(cache=True)
def _jump_share(t1, t2, lim, v, acap_near):
    """The largest share of an axis' acceleration (or of the path's) that an unblended joint passed at v or
    less takes over the two ticks around it, (v + 2T·A_t)|Δτ_i| / (T a_i): at most γ, by its cap."""
    T = lim[L_PERIOD]
    share = 0.0
    total = 0.0
    for i in range(3):
        dt = abs(t2[i] - t1[i])
        total += dt * dt
        share = max(share, (v + 2.0 * T * acap_near) * dt / (T * lim[L_ACC + i]))
    share = max(share, (v + 2.0 * T * acap_near) * math.sqrt(total) / (T * lim[L_ACCEL]))
    return min(share * (1.0 + 1e-9), lim[L_GAMMA])


@njit(cache=True)
def _blend_crawls(R, theta, t1, inward, vcap, feed, lim):
    """Whether a corner blend (radius R, turn θ, entered along t1 turning towards *inward*, cap *vcap*, between
    blocks of feed *feed*) is better taken at rest under the axes' jerk limits: crossing it at the speed they allow
    takes longer than stopping on the corner and starting again.

    Where a line meets its blend an axis' acceleration jumps by V² κ |n_i| (n the inward normal at that end), and
    motion.jerk keeps the jump's third difference, STEP_JUMP V² κ |n_i| / T, within the axes' jump share; inside
    the blend V³ κ² stays within the speed share: so the blend is crossed at v or less.  Braking along the same
    jerk-limited profile, the tool reaches the blend's start (d = R tan(θ/2) before the corner) at v and crosses
    it in R θ / v; or it goes on braking to rest on the corner, which costs, both sides, the stop from v and back
    (4 √(v/J) at the ramps' jerk J), a tick at rest, and the 2d of legs it runs instead of the blend (2d/F
    where the legs run at F, more where they are slower; the stop's term is generous).  A 90° corner
    within 5 µm (R = 12 µm) is crossed at some 0.4 mm/s at 20 000 mm/s³, 47 ms for its 19 µm, where the
    rest costs 27 ms (measured on the raster of benchmarks/cam.py: 0.12 s less a row change).  Without a jerk
    limit a blend is passed at √(A R) and always kept."""
    kappa = 1.0 / R
    c = math.cos(theta)
    sn = math.sin(theta)
    v = vcap
    for i in range(3):
        j = lim[L_JERK + i]
        if not j < math.inf:
            continue
        n_out = abs(-sn * t1[i] + c * inward[i])  # the inward normal where the blend meets the next line
        n = max(abs(inward[i]), n_out)
        if n > 0.0:
            v = min(v, math.sqrt(lim[L_JUMP_SHARE] * j * lim[L_PERIOD] / (STEP_JUMP * kappa * n)))
        v = min(v, (lim[L_SPEED_SHARE] * j / (kappa * kappa)) ** (1.0 / 3.0))
    if not v < vcap or not lim[L_RAMP_JERK] < math.inf:
        return False  # no jerk limit slows it
    d = R * math.tan(0.5 * theta)
    return R * theta / v > 4.0 * math.sqrt(v / lim[L_RAMP_JERK]) + 2.0 * d / feed + lim[L_PERIOD]


@njit(cache=True)
def _smallest_blend(d, R, theta, q, probe, feed, tol, lim):
    """The blend of a corner between blocks of different feeds (a rapid into a cut, a plunge): no larger than it
    takes to pass the corner as fast as the blend of size *d* does, so that the faster block is not run at the
    slower's feed over more of its length than that (on vcarve.ngc a retract's blend at F6 cost 0.23 s where
    stopping cost 0.1 ms).  Bisection on the size: the caps grow with the radius.  *probe* holds the caps of
    the blend returned; (d, R) are returned."""
    target = probe[VCAP] * (1.0 - 1e-12)
    ct = 1.0 / math.tan(0.5 * theta)
    lo = 0.0
    hi = d
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if not mid > lo or not mid < hi:
            break
        probe[RADIUS] = mid * ct
        _arc_caps(probe, feed, lim, math.inf, lim[L_BLEND_BETA])
        sag = probe[VCAP] * probe[VCAP] * lim[L_PERIOD] * lim[L_PERIOD] / (8.0 * probe[RADIUS])
        if probe[VCAP] >= target and mid * q + sag <= tol:
            hi = mid
        else:
            lo = mid
    probe[RADIUS] = hi * ct
    _arc_caps(probe, feed, lim, math.inf, lim[L_BLEND_BETA])
    return hi, hi * ct


@njit(cache=True)
def build_segments(kind, P0, P1, C, N, sweep, rise, feed, rapid, ctrl, tol, stop, dwell, block, upieces, curves,
                   lim, d_in, last, out):
    """The segments of blocks 0 .. K−2 of a batch (and of K−1 too when *last*), written into *out*.

    Block arrays (K,) or (K, 3): kind (LINE/ARC/CURVE), start, end, centre, axis, sweep, rise, feedrate (mm/s,
    resolved), rapid, control mode, blend tolerance (mm; 0: none), stop before the block (1), dwell before it (s),
    the block's index in the program, its arc's NURBS pieces (for u).  A CURVE block (a run of moves refitted by
    motion.smooth) is rows made already, with their caps: ``curves[rise : rise + upieces]``; its unit end
    tangents are in C and N, its length in sweep.  *d_in*: how much of block 0's start a blend took (mm), and
    its start node as (cap, stop, dwell) in d_in[1:4].  Returns (rows written, the same four values for block K−1).
    Each block's first row carries its start node: NODECAP, STOP, DWELL.
    """
    K = kind.shape[0]
    m = 0
    n_blocks = K if last else K - 1
    trim_in = d_in[0]
    node_cap = d_in[1]
    node_stop = d_in[2]
    node_dwell = d_in[3]
    unblended_in = d_in[4]  # block 0's start joint is an unblended turn (its cap already includes the share)
    TS = np.empty((K, 3))
    TE = np.empty((K, 3))
    LS = np.empty(K)
    _tangents(kind, P0, P1, C, N, sweep, rise, TS, TE, LS)
    probe = np.zeros(NCOL)
    inward = np.zeros(3)
    blend_inward = np.zeros(3)
    for b in range(n_blocks):
        t_start = TS[b]
        t_end = TE[b]
        L = LS[b]
        # the end joint
        trim_out = 0.0
        blend_theta = 0.0
        blend_R = 0.0
        blend_vcap = 0.0
        blend_acap = 0.0
        nxt_cap = 0.0
        nxt_stop = 1.0
        nxt_dwell = 0.0
        unblended_out = 0.0
        if b + 1 < K:
            n_start = TS[b + 1]
            Ln = LS[b + 1]
            theta = _turn(t_end, n_start, inward)
            nxt_stop = 0.0
            nxt_cap = math.inf
            # the exact path: no blend, and no tolerance for the tick that straddles a joint to cut its corner by
            exact = ctrl[b] == EXACT_PATH or not tol[b] > 0.0
            if stop[b + 1] != 0 or dwell[b + 1] > 0.0 or ctrl[b] == EXACT_STOP or theta >= REVERSAL:
                nxt_stop = 1.0
                nxt_cap = 0.0
                nxt_dwell = dwell[b + 1]
            elif theta > 0.0:
                # the unblended joint's cap, with the acceleration the lines beside it keep (1 − γ)
                acap_near = math.inf
                for i in range(3):
                    for tt in (t_end[i], n_start[i]):
                        if abs(tt) > 0.0:
                            acap_near = min(acap_near, lim[L_ACC + i] / abs(tt))
                acap_near = min(acap_near, lim[L_ACCEL])
                if acap_near == math.inf:
                    acap_near = 0.0
                jump = _jump_cap(t_end, n_start, lim, (1.0 - lim[L_GAMMA]) * acap_near)
                blended = False
                at_rest = False
                if kind[b] == LINE and kind[b + 1] == LINE and not exact:
                    q = math.tan(0.25 * theta)
                    d = min(tol[b] / q, 0.5 * L, 0.5 * Ln)
                    R = 0.0
                    for _ in range(8):
                        # the commands are chords of the blend: at the feed V its chord of one tick sags by
                        # (VT)²/8R inside it, which the corner's distance to the commands adds to e = d tan(θ/4)
                        if not d > MIN_BLEND:
                            break
                        R = d / math.tan(0.5 * theta)
                        # the blend's cap: the caps of an arc of radius R in the corner's plane
                        for i in range(3):
                            probe[D + i] = -inward[i]
                            probe[E + i] = t_end[i]
                        # the axis e1 × e2 (no need: a circle's caps do not depend on it)
                        probe[RADIUS] = R
                        probe[SWEEP] = theta
                        _arc_caps(probe, min(feed[b], feed[b + 1]), lim, math.inf, lim[L_BLEND_BETA])
                        sag = probe[VCAP] * probe[VCAP] * lim[L_PERIOD] * lim[L_PERIOD] / (8.0 * R)
                        if d * q + sag <= tol[b]:
                            break
                        d = min(d, (tol[b] - sag) / q) * (1.0 - 1e-9)
                    if d > MIN_BLEND:  # the radius and caps of the last d (the loop may end on a lowered d)
                        R = d / math.tan(0.5 * theta)
                        probe[RADIUS] = R
                        _arc_caps(probe, min(feed[b], feed[b + 1]), lim, math.inf, lim[L_BLEND_BETA])
                    if d > MIN_BLEND and feed[b] != feed[b + 1] \
                            and d * q + probe[VCAP] ** 2 * lim[L_PERIOD] ** 2 / (8.0 * R) <= tol[b]:
                        d, R = _smallest_blend(d, R, theta, q, probe, min(feed[b], feed[b + 1]), tol[b], lim)
                    if d > MIN_BLEND and d * q + probe[VCAP] ** 2 * lim[L_PERIOD] ** 2 / (8.0 * R) <= tol[b]:
                        # a blend costs the lines beside it nothing, an unblended joint a share of their
                        # acceleration: the blend, unless it is slower than the joint could be passed
                        if _blend_crawls(R, theta, t_end, inward, probe[VCAP], min(feed[b], feed[b + 1]), lim):
                            at_rest = True
                        elif probe[VCAP] >= min(jump, feed[b], feed[b + 1]) * (1.0 - 1e-12):
                            blended = True
                            trim_out = d
                            blend_theta = theta
                            blend_R = R
                            blend_inward[:] = inward
                            blend_vcap = probe[VCAP]
                            blend_acap = probe[ACAP]
                if at_rest:  # no blend, and no joint passed moving: the corner at rest
                    nxt_stop = CORNER_REST
                    nxt_cap = 0.0
                elif not blended:
                    # the tick that straddles the joint cuts its corner by at most (VT/2) sin(θ/2): within the
                    # tolerance (a kink of rounding size, at most EXACT_PATH_KINK, is a tangent joint); on the exact
                    # path only the ticks are held to the path, as a controller's exact-path mode holds them
                    if theta > EXACT_PATH_KINK and not exact:
                        jump = min(jump, 2.0 * tol[b] / (lim[L_PERIOD] * math.sin(0.5 * theta)))
                    nxt_cap = jump
                    # the share of the axes' acceleration the jump takes at the fastest the joint can be passed
                    # (its cap, or the blocks' feedrates): the lines beside it keep the rest for the tangential
                    # part -- at most γ, and nearly nothing at a kink far below the limits.  A joint too sharp to
                    # pass moving (cap 0) is a stop: no jump there, so the lines keep their whole acceleration
                    if jump > 0.0:
                        unblended_out = _jump_share(t_end, n_start, lim, min(jump, max(feed[b], feed[b + 1])),
                                                    (1.0 - lim[L_GAMMA]) * acap_near)
        # block b itself
        first = m
        if kind[b] == LINE:
            if L - trim_in - trim_out > 0.0:
                m = _put_line(out, m, P0[b], t_start, trim_in, L - trim_in - trim_out, block[b], trim_in / L, 1.0 / L,
                              feed[b], rapid[b], lim)
                if unblended_in != 0.0 or unblended_out != 0.0:
                    row = out[m - 1]
                    row[ACAP] *= 1.0 - max(unblended_in, unblended_out)
                    if unblended_in != 0.0 and unblended_out != 0.0:
                        row[VCAP] = min(row[VCAP], row[LEN] / (STRADDLE_TICKS * lim[L_PERIOD]))
        elif kind[b] == CURVE:
            r0 = int(rise[b])
            nr = int(upieces[b])
            share = 1.0 - max(unblended_in, unblended_out)
            for r in range(nr):
                out[m] = curves[r0 + r]
                out[m, ACAP] *= share
                m += 1
        else:
            e1, e2, R = _arc_frame(P0[b], C[b], N[b])
            m = _put_arc(out, m, P0[b].copy(), e1, e2, N[b], R, sweep[b], rise[b], block[b], U_ARC, upieces[b],
                         sweep[b] / upieces[b], 0.0, feed[b], rapid[b], lim, tol[b] if tol[b] > 0.0 else math.inf)
            if unblended_in != 0.0 or unblended_out != 0.0:
                out[m - 1, ACAP] *= 1.0 - max(unblended_in, unblended_out)
        # the blend at its end: two halves, the first on block b's side of the corner, the second on b + 1's
        if trim_out > 0.0:
            t1 = t_end
            e1 = -blend_inward
            e2 = t1.copy()
            axis = _cross(e1, e2)
            half = 0.5 * blend_theta
            a_pt = P1[b] - trim_out * t1
            fe = min(feed[b], feed[b + 1])
            Lb = L
            Ln = math.sqrt(((P1[b + 1] - P0[b + 1]) ** 2).sum())
            m = _put_arc(out, m, a_pt, e1, e2, axis, blend_R, half, 0.0, block[b], U_BLEND_IN, (Lb - trim_out) / Lb,
                         1.0 / Lb, 0.0, fe, rapid[b] * rapid[b + 1], lim, math.inf)
            ch, sh = math.cos(half), math.sin(half)
            q2 = math.sin(0.5 * half)
            mid = a_pt + blend_R * (-2.0 * q2 * q2 * e1 + sh * e2)  # cos − 1 as −2 sin²: R may be 1e6 mm
            f1 = ch * e1 + sh * e2
            f2 = -sh * e1 + ch * e2
            m = _put_arc(out, m, mid, f1, f2, axis, blend_R, half, 0.0, block[b + 1], U_BLEND_OUT, trim_out / Ln,
                         1.0 / Ln, half, fe, rapid[b] * rapid[b + 1], lim, math.inf)
            # both halves at the whole blend's caps, which its sag was checked with (a half's own may be higher)
            for r in (m - 2, m - 1):
                out[r, VCAP] = blend_vcap
                out[r, ACAP] = blend_acap
        if m > first:  # the block's start node goes with its first row (its line, or its blend when the
            out[first, NODECAP] = node_cap  # blends on both sides took the whole line)
            out[first, STOP] = node_stop
            out[first, DWELL] = node_dwell
            node_cap = nxt_cap
            node_stop = nxt_stop
            node_dwell = nxt_dwell
        else:  # nothing of the block is left: its start node and its end joint are one node
            node_cap = min(node_cap, nxt_cap)
            node_stop = max(node_stop, nxt_stop)
            node_dwell = node_dwell + nxt_dwell
        trim_in = trim_out
        unblended_in = unblended_out
    d_out = np.array([trim_in, node_cap, node_stop, node_dwell, unblended_in])
    return m, d_out


@njit(cache=True)
def segment_point(row, s, out):
    """The point at arc length s from the segment's start (0 <= s <= LEN), into out (3,); returns the parameter
    segment_u needs (a curve's Bézier parameter w; s otherwise).

    An arc is evaluated from its start point, R((cos θ − 1) e1 + sin θ e2), with cos θ − 1 = −2 sin²(θ/2): a
    blend of a tiny turn has a huge radius, and the point is then as accurate as its arc length, not its radius."""
    if row[KIND] == LINE:
        for i in range(3):
            out[i] = row[P + i] + s * row[D + i]
        return s
    if row[KIND] == CURVE:
        w = bezier_parameter(row, s)
        a = 1.0 - w
        c0 = a * a * a
        c1 = 3.0 * a * a * w
        c2 = 3.0 * a * w * w
        c3 = w * w * w
        for i in range(3):
            out[i] = c0 * row[B0 + i] + c1 * row[B1 + i] + c2 * row[B2 + i] + c3 * row[B3 + i]
        return w
    L = row[LEN]
    th = s / L * row[SWEEP]
    R = row[RADIUS]
    sh = math.sin(0.5 * th)
    cm1 = -2.0 * sh * sh
    sn = math.sin(th)
    r = row[RISE] * (s / L)
    for i in range(3):
        out[i] = row[P + i] + R * (cm1 * row[D + i] + sn * row[E + i]) + r * row[NRM + i]
    return s


@njit(cache=True)
def segment_u(row, s, w):
    """The block's own parameter at arc length s along the segment: the point of the programmed block that the
    command stands for.

    A line's u is its fraction of the block's length (its degree-1 NURBS parameter); an arc block's is the
    parameter of its rational quadratic pieces (one per quarter turn at most, path.block_nurbs): in a piece of
    angle 2α (middle weight cos α), the point at angle ψ has t = tan(ψ/2) / (sin α + tan(ψ/2)(1 − cos α)).
    On a blend, u is that of the foot on the line it replaces: the point of the tangent line R·tan ψ from where
    the blend leaves it.  On a refitted curve, u is the chord-length parameter the fit gave the move, which the
    Bézier parameter w follows linearly (each curve row lies over one move)."""
    kind = int(row[UKIND])
    if kind == U_LINEAR:
        return row[U0] + s * row[DU]
    if kind == U_CURVE:
        return row[U0] + w * row[DU]
    th = s / row[LEN] * row[SWEEP]
    if kind == U_BLEND_IN:
        return row[U0] + row[DU] * row[RADIUS] * math.tan(th)
    if kind == U_BLEND_OUT:
        return row[U0] - row[DU] * row[RADIUS] * math.tan(row[UANG] - th)
    pieces = row[U0]
    step = row[DU]
    k = min(math.floor(th / step), pieces - 1.0)
    psi = th - k * step
    # the piece from angle 0 to 2α = step, weight cos α at its middle: tan(ψ/2) = t sin α / ((1 − t) + t cos α)
    half = 0.5 * step
    q = math.tan(0.5 * psi)
    t = q / (math.sin(half) + q * (1.0 - math.cos(half)))
    return (k + t) / pieces


# 8-point Gauss-Legendre on [-1, 1] (numpy.polynomial.legendre.leggauss(8)), for a curve row's arc length: exact
# for polynomials of degree 15, and a row's speed |B'| is the square root of a quartic varying by a few per cent
# over the row (one short move of a smooth curve), whose Taylor terms fall by that ratio each
_GL_X = np.polynomial.legendre.leggauss(8)[0]
_GL_W = np.polynomial.legendre.leggauss(8)[1]


@njit(cache=True)
def bezier_speed(row, w):
    """|B'(w)| of a curve row's cubic Bézier."""
    a = 1.0 - w
    c0 = 3.0 * a * a
    c1 = 6.0 * a * w
    c2 = 3.0 * w * w
    total = 0.0
    for i in range(3):
        d = c0 * (row[B1 + i] - row[B0 + i]) + c1 * (row[B2 + i] - row[B1 + i]) + c2 * (row[B3 + i] - row[B2 + i])
        total += d * d
    return math.sqrt(total)


@njit(cache=True)
def bezier_length(row, w):
    """Arc length of a curve row from its start to the parameter w (8-point Gauss-Legendre on [0, w]: a row
    spans one short move of a smooth curve, whose speed |B'| varies by a few per cent at most over it, so that
    the rule is exact to rounding: tests/test_smooth.py checks it against scipy's quad to 1e-11).  A row's LEN
    is bezier_length(row, 1.0), so that the same rule maps arc length to w and back."""
    half = 0.5 * w
    total = 0.0
    for q in range(8):
        total += _GL_W[q] * bezier_speed(row, half + half * _GL_X[q])
    return half * total


@njit(cache=True)
def bezier_lengths(rows):
    """LEN of curve rows (n, NCOL) made in Python: bezier_length at w = 1."""
    out = np.empty(rows.shape[0])
    for i in range(rows.shape[0]):
        out[i] = bezier_length(rows[i], 1.0)
    return out


@njit(cache=True)
def bezier_parameter(row, s):
    """The Bézier parameter w of the point at arc length s along a curve row: Newton's method on
    bezier_length(w) = s from w = s/LEN (the rows' parameter is nearly proportional to arc length), safeguarded
    by bisection, to |length − s| <= 1e-13 LEN (then once more: Newton's step is quadratic)."""
    L = row[LEN]
    if s <= 0.0:
        return 0.0
    if s >= L:
        return 1.0
    lo = 0.0
    hi = 1.0
    w = s / L
    for _ in range(60):
        f = bezier_length(row, w) - s
        if f > 0.0:
            hi = w
        else:
            lo = w
        sp = bezier_speed(row, w)
        nw = w - f / sp if sp > 0.0 else 0.5 * (lo + hi)
        if not (lo <= nw <= hi):
            nw = 0.5 * (lo + hi)
        done = abs(f) <= 1e-13 * L
        w = nw
        if done or hi - lo <= 1e-16:
            break
    return w


def _bernstein_inverse(degree):
    """The matrix taking a polynomial's values at degree + 1 equispaced points of [0, 1] to its Bernstein
    coefficients there."""
    v = np.linspace(0.0, 1.0, degree + 1)
    M = np.array([[math.comb(degree, j) * x ** j * (1 - x) ** (degree - j) for j in range(degree + 1)] for x in v])
    return np.linalg.inv(M)


_BERN5 = _bernstein_inverse(5)
_BERN6 = _bernstein_inverse(6)
BOUND_DEPTH = 8  # halvings of a curve row's interval, at most, before its bounds are taken as they are


@njit(cache=True)
def _bezier_d1(row, w, out):
    a = 1.0 - w
    c0 = 3.0 * a * a
    c1 = 6.0 * a * w
    c2 = 3.0 * w * w
    for i in range(3):
        out[i] = c0 * (row[B1 + i] - row[B0 + i]) + c1 * (row[B2 + i] - row[B1 + i]) + c2 * (row[B3 + i] - row[B2 + i])


@njit(cache=True)
def _bezier_d2(row, w, out):
    for i in range(3):
        out[i] = 6.0 * ((1.0 - w) * (row[B2 + i] - 2.0 * row[B1 + i] + row[B0 + i])
                        + w * (row[B3 + i] - 2.0 * row[B2 + i] + row[B1 + i]))


@njit(cache=True)
def _interval_bound(row, lo, hi, bounds, sampled):
    """Bounds over w in [lo, hi] of a curve row (see curve_bounds) into bounds[0:7] (κ, |τ_i|, |κn_i|), and the
    same quantities' largest values at 7 equispaced points into sampled[0:7]."""
    D1 = np.empty((7, 3))
    D2 = np.empty((7, 3))
    for q in range(7):
        w = lo + (hi - lo) * q / 6.0
        _bezier_d1(row, w, D1[q])
        _bezier_d2(row, w, D2[q])
    # derivatives in a parameter c·w, c = 1 / max |B'| here: κ, τ and κn do not depend on the parameter, and a
    # row of 1e-16 mm (a knot beside a vertex) would otherwise underflow |B'|⁴; a polynomial in w stays one in
    # v = (w − lo) / (hi − lo)
    top = 0.0
    for q in range(7):
        top = max(top, math.sqrt(D1[q, 0] ** 2 + D1[q, 1] ** 2 + D1[q, 2] ** 2))
    scale = 1.0 / top if top > 0.0 else 1.0
    for q in range(7):
        for i in range(3):
            D1[q, i] *= scale
            D2[q, i] *= scale * scale
    # hodograph Bernstein coefficients from its values at v = 0, 1/2, 1
    H = np.empty((3, 3))
    for i in range(3):
        H[0, i] = D1[0, i]
        H[2, i] = D1[6, i]
        H[1, i] = 2.0 * D1[3, i] - 0.5 * (D1[0, i] + D1[6, i])
    dn = math.sqrt(D1[3, 0] ** 2 + D1[3, 1] ** 2 + D1[3, 2] ** 2)
    smin = math.inf
    if dn > 0.0:
        for j in range(3):
            smin = min(smin, (H[j, 0] * D1[3, 0] + H[j, 1] * D1[3, 1] + H[j, 2] * D1[3, 2]) / dn)
    ok = top > 0.0 and dn > 0.0 and smin > 1e-12  # (|B'| ~ 1 here: below 1e-12 of it, a cusp)
    # g = |D1|²|D2|² − (D1·D2)², degree 6: its Bernstein coefficients from the 7 values
    g = np.empty(7)
    for q in range(7):
        s2 = D1[q, 0] ** 2 + D1[q, 1] ** 2 + D1[q, 2] ** 2
        d2 = D2[q, 0] ** 2 + D2[q, 1] ** 2 + D2[q, 2] ** 2
        dot = D1[q, 0] * D2[q, 0] + D1[q, 1] * D2[q, 1] + D1[q, 2] * D2[q, 2]
        g[q] = s2 * d2 - dot * dot
        sp = math.sqrt(s2)
        k = math.sqrt(max(g[q], 0.0)) / (sp * sp * sp) if s2 > 1e-150 else 0.0
        sampled[0] = max(sampled[0], k) if q > 0 else k
        for i in range(3):
            t = abs(D1[q, i]) / sp if s2 > 1e-150 else 0.0
            kv = abs(D2[q, i] * s2 - D1[q, i] * dot) / (s2 * s2) if s2 > 1e-150 else 0.0
            sampled[1 + i] = max(sampled[1 + i], t) if q > 0 else t
            sampled[4 + i] = max(sampled[4 + i], kv) if q > 0 else kv
    if not ok:
        for j in range(7):
            bounds[j] = math.inf
        for i in range(3):
            bounds[1 + i] = 1.0
        return
    gmax = 0.0
    for j in range(7):
        c = 0.0
        for q in range(7):
            c += _BERN6[j, q] * g[q]
        gmax = max(gmax, c)
    kappa = math.sqrt(gmax) / (smin * smin * smin)
    bounds[0] = kappa
    for i in range(3):
        bounds[1 + i] = min(max(abs(H[0, i]), abs(H[1, i]), abs(H[2, i])) / smin, 1.0)
    # the curvature vector's numerator D2|D1|² − D1(D1·D2), degree 5: its values at 6 points, afresh
    E1 = np.empty(3)
    E2 = np.empty(3)
    num = np.empty((6, 3))
    for q in range(6):
        w = lo + (hi - lo) * q / 5.0
        _bezier_d1(row, w, E1)
        _bezier_d2(row, w, E2)
        for i in range(3):
            E1[i] *= scale
            E2[i] *= scale * scale
        s2 = E1[0] ** 2 + E1[1] ** 2 + E1[2] ** 2
        dot = E1[0] * E2[0] + E1[1] * E2[1] + E1[2] * E2[2]
        for i in range(3):
            num[q, i] = E2[i] * s2 - E1[i] * dot
    s4 = smin ** 4
    for i in range(3):
        m = 0.0
        for j in range(6):
            c = 0.0
            for q in range(6):
                c += _BERN5[j, q] * num[q, i]
            m = max(m, abs(c))
        bounds[4 + i] = min(m / s4, kappa)


@njit(cache=True)
def push_halves(stack_lo, stack_hi, stack_d, top, lo, hi, depth):
    """Push the halves of [lo, hi] (the lower on top, taken next) one level deeper; returns the new top."""
    mid = 0.5 * (lo + hi)
    stack_lo[top] = mid
    stack_hi[top] = hi
    stack_d[top] = depth + 1
    stack_lo[top + 1] = lo
    stack_hi[top + 1] = mid
    stack_d[top + 1] = depth + 1
    return top + 2


@njit(cache=True)
def curve_bounds(rows, slack, out):
    """Rigorous upper bounds, per curve row, of its curvature κ, of each axis's unit-tangent component |τ_i| and
    of each axis's curvature-vector component |κ n_i| (= |dτ_i/ds|), into out (n, 7).

    On an interval of the row's Bézier parameter, with v in [0, 1] across it: the hodograph B'(v) is a quadratic
    whose Bernstein coefficients H_j bound |B'_i| (convex hull), and along the unit d of B'(1/2) the speed from
    below, s_min = min_j <H_j, d>; g = |B'|²|B''|² − (B'·B'')² = |B' × B''|² is of degree 6, its largest
    Bernstein coefficient bounds it, so κ <= sqrt(max) / s_min³; the curvature vector's numerator
    B''|B'|² − B'(B'·B'') is of degree 5 over |B'|⁴ >= s_min⁴; |τ_i| <= max_j |H_j,i| / s_min.  These converge to
    the maxima as the interval shrinks: an interval whose bounds exceed the values at its 7 points by more than
    *slack* (relative, or 1e-9 absolute) is halved, up to BOUND_DEPTH times (the bounds are then within about
    *slack* of the maxima).  An interval where s_min <= 0 (a cusp) bounds nothing: inf (|τ_i| 1)."""
    bounds = np.empty(7)
    sampled = np.empty(7)
    stack_lo = np.empty(2 * BOUND_DEPTH + 2)
    stack_hi = np.empty(2 * BOUND_DEPTH + 2)
    stack_d = np.empty(2 * BOUND_DEPTH + 2, dtype=np.int64)
    for r in range(rows.shape[0]):
        row = rows[r]
        for j in range(7):
            out[r, j] = 0.0
        top = 0
        stack_lo[0] = 0.0
        stack_hi[0] = 1.0
        stack_d[0] = 0
        top = 1
        while top > 0:
            top -= 1
            lo = stack_lo[top]
            hi = stack_hi[top]
            depth = stack_d[top]
            _interval_bound(row, lo, hi, bounds, sampled)
            good = depth >= BOUND_DEPTH
            if not good:
                good = True
                for j in range(7):
                    if not bounds[j] <= sampled[j] * (1.0 + slack) + 1e-9:
                        good = False
                        break
            if good:
                for j in range(7):
                    out[r, j] = max(out[r, j], bounds[j])
            else:
                top = push_halves(stack_lo, stack_hi, stack_d, top, lo, hi, depth)
