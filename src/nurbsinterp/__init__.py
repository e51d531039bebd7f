"""nurbsinterp: real-time variable-feedrate NURBS interpolation for CNC motion.

Pipeline (one module per stage)::

    spec → nurbs → profiles → interpolate → streams
    servo → metrics

Conventions: lengths in mm, times in s, feedrate in mm/s.  Degree p
(order = p + 1, the paper's k).

Importing the package is cheap: numpy and numba load with the first module
that needs them (``from nurbsinterp import NurbsCurve`` does), so that
``nurbsinterp --version`` starts as fast as Python itself.
"""
from ._cache import use_source_keyed_cache
from ._version import __version__

use_source_keyed_cache()  # before any kernel module imports numba

__all__ = ["NurbsCurve", "NurbsInterpError", "SpecError", "StreamError", "__version__"]


def __getattr__(name):
    if name == "NurbsCurve":
        from .nurbs import NurbsCurve

        return NurbsCurve
    if name in ("NurbsInterpError", "SpecError", "StreamError"):
        from . import errors

        return getattr(errors, name)
    raise AttributeError(f"module 'nurbsinterp' has no attribute {name!r}")
