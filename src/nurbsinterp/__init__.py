"""nurbsinterp: real-time variable-feedrate NURBS interpolation for CNC motion.

Pipeline (one module per stage)::

    spec → nurbs → profiles → interpolate → streams
    servo → metrics

Conventions: lengths in mm, times in s, feedrate in mm/s.  Degree p
(order = p + 1, the paper's k).
"""
from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("nurbsinterp")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

from ._cache import use_source_keyed_cache  # noqa: E402

use_source_keyed_cache()  # before any kernel module is imported

from .errors import NurbsInterpError, SpecError, StreamError  # noqa: E402
from .nurbs import NurbsCurve  # noqa: E402

__all__ = ["NurbsCurve", "NurbsInterpError", "SpecError", "StreamError", "__version__"]
