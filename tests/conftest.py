"""Shared test data: the paper's circle and seeded random NURBS curves."""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, settings

sys.path.insert(0, str(Path(__file__).parent))  # so that test modules can `import oracle`

# No test may depend on the machine's speed: hypothesis's default 200 ms deadline per example, and its health
# check on slow data generation, both fail a correct test on a busy machine.  Loaded before any test module
# builds its own settings, which inherit from it.
settings.register_profile("nurbsinterp", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("nurbsinterp")

CURVES_DIR = Path(__file__).parent.parent / "curves"

#: The paper's test curve (Fig. 6): circle of radius 50 mm centred at (50, 0).
CIRCLE = dict(
    degree=2,
    control_points=[[0, 0], [0, 50], [100, 50], [100, 0], [100, -50], [0, -50], [0, 0]],
    weights=[1, 0.5, 0.5, 1, 0.5, 0.5, 1],
    knots=[0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1],
)
CIRCLE_CENTRE = np.array([50.0, 0.0])
CIRCLE_RADIUS = 50.0

#: Parameter domains of the random curves: none is [0, 1]; one is tiny (huge derivatives).
DOMAINS = [(-3.7, 12.1), (2.0, 7.0), (-50.0, -10.0), (0.001, 0.013)]
SEEDS = list(range(20))


@dataclass(frozen=True)
class CurveData:
    """Plain NURBS data (degree p, knots U, control points V, weights W)."""

    p: int
    U: np.ndarray
    V: np.ndarray
    W: np.ndarray

    @property
    def domain(self) -> tuple[float, float]:
        return float(self.U[self.p]), float(self.U[-self.p - 1])

    def curve(self):
        from nurbsinterp.nurbs import NurbsCurve

        return NurbsCurve(self.p, self.V, self.W, self.U)


def random_curve_data(seed: int) -> CurveData:
    """A seeded random clamped NURBS: degree 1–5, 2-D or 3-D, weights in [0.2, 5].

    Interior knots are at least 2 % of the domain apart; each has a multiplicity
    in 1..p, and at least one has multiplicity exactly p (a C^0 join).
    """
    rng = np.random.default_rng(seed)
    p = int(rng.integers(1, 6))
    dim = int(rng.integers(2, 4))
    a, b = DOMAINS[seed % len(DOMAINS)]
    count = int(rng.integers(1, 6))
    gaps = rng.uniform(1.0, 5.0, count + 1)
    inner = a + (b - a) * np.cumsum(gaps)[:-1] / gaps.sum()
    mult = rng.integers(1, p + 1, count)
    mult[rng.integers(count)] = p
    U = np.concatenate([[a] * (p + 1), np.repeat(inner, mult), [b] * (p + 1)])
    n_ctrl = len(U) - p - 1
    V = rng.uniform(-100.0, 100.0, (n_ctrl, dim))
    W = rng.uniform(0.2, 5.0, n_ctrl)
    return CurveData(p, U, V, W)


def span_index(U: np.ndarray, p: int, u: np.ndarray) -> np.ndarray:
    """Index i of the knot span [U_i, U_{i+1}) holding u (right-continuous, end -> last span)."""
    n = len(U) - p - 2
    i = np.searchsorted(U, u, side="right") - 1
    return np.clip(i, p, n)


def per_span_scale(U: np.ndarray, p: int, u: np.ndarray, values: np.ndarray, size: float = 0.0) -> np.ndarray:
    """Scale of each derivative order on each knot span: max |C^(k)| over the samples.

    values : (N, order+1, dim) at parameters u.  Returns (N, order+1): for each
    sample, the largest norm of the same derivative among the samples of its span
    (the polynomial piece it belongs to), and at least size / h^k, the natural
    size of the k-th derivative of a piece of amplitude *size* on a span of
    width h (it matters only where the values themselves nearly vanish, e.g. a
    curve shrunk to a point far from the origin).
    """
    spans = span_index(U, p, u)
    norms = np.linalg.norm(values, axis=-1)
    scale = np.empty_like(norms)
    orders = np.arange(norms.shape[1])
    for s in np.unique(spans):
        sel = spans == s
        scale[sel] = np.maximum(norms[sel].max(axis=0), size / (U[s + 1] - U[s]) ** orders)
    return np.maximum(scale, 1e-300)


import pytest  # noqa: E402

# --------------------------------------------------------------------------- the quick set and the slow set
#
# `python -m pytest` runs the quick set: every contract once, the hypothesis properties on a smaller budget
# (with the example database kept, so that a failure found once is replayed first), on two xdist workers
# (pyproject.toml).  `python -m pytest -m slow` runs the slow set: the full budgets, the long runs (10**7
# ticks) and the repeats of a contract over more sizes, writers and options.  CI (.ci/run) runs both; a test
# that ran before the split runs in one of them, with its full budget.

#: the quick set's longest tests, started first so that the two workers end together (on a 2-core machine a
#: five-minute test that started last would run alone at the end); they are found by name, a renamed one
#: only starts later
LONGEST_FIRST = (
    "tests/test_startup.py::test_a_first_run_compiles_only_what_the_command_calls_and_says_so",
    "tests/test_startup.py::test_a_signal_while_compiling_ends_the_run[2-130-interrupted]",
)


def pytest_collection_modifyitems(config, items):
    first = [item for item in items if item.nodeid in LONGEST_FIRST]
    if first:
        items[:] = first + [item for item in items if item.nodeid not in LONGEST_FIRST]


def pytest_sessionstart(session):
    """Compile every kernel once, before the first test, in the process that starts the xdist workers: left to
    the workers, each would compile the same kernels at the same time."""
    config = session.config
    if hasattr(config, "workerinput") or config.option.collectonly:
        return  # an xdist worker: the controller has compiled them before starting it
    from nurbsinterp._cache import kernels_warm, mark_warm

    if kernels_warm():
        return
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line("compiling the numeric kernels once, before the tests (about 2 minutes on 2 cores in a "
                            "fresh clone; `nurbsinterp warmup` does the same)")
    import os

    from nurbsinterp.warmup import warm_up

    warm_up(jobs=os.cpu_count() or 1)  # on every core, as `nurbsinterp warmup`
    mark_warm()


@pytest.fixture(scope="session", autouse=True)
def compiled_kernels():
    """Compile every kernel once before the first test, as `nurbsinterp warmup` does.

    pytest_sessionstart (above) has done it already, before any worker started; this is the safety net of a
    worker whose cache is not the controller's.  Without it the first CLI test of a fresh checkout would run
    the first-run warm-up itself and find its notice on stderr; the warm-up's own notice is tested in
    test_startup.py.
    """
    from nurbsinterp._cache import kernels_warm, mark_warm
    from nurbsinterp.warmup import warm_up

    if not kernels_warm():
        warm_up()
        mark_warm()
