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
try:
    from ._cache import use_source_keyed_cache
    from ._version import __version__

    use_source_keyed_cache()  # before any kernel module imports numba
except (KeyboardInterrupt, RuntimeError) as _exc:
    # A Ctrl-C this early lands before the console script (_entry) can catch it: the script ends as
    # _entry would, with exit 130 and one line.  (Inside a class body the interrupt may come wrapped in
    # a RuntimeError: "Error calling __set_name__".)  Imported as a library, the exception is the caller's.
    import os as _os
    import sys as _sys

    _interrupt = isinstance(_exc, KeyboardInterrupt) or isinstance(_exc.__cause__, KeyboardInterrupt)
    if not _interrupt or _os.path.basename(_sys.argv[0] if _sys.argv else "") != "nurbsinterp":
        raise
    _sys.stderr.write("nurbsinterp: interrupted\n")
    raise SystemExit(130) from None

__all__ = ["NurbsCurve", "NurbsInterpError", "SpecError", "StreamError", "__version__"]


def __getattr__(name):
    if name == "NurbsCurve":
        from .nurbs import NurbsCurve

        return NurbsCurve
    if name in ("NurbsInterpError", "SpecError", "StreamError"):
        from . import errors

        return getattr(errors, name)
    raise AttributeError(f"module 'nurbsinterp' has no attribute {name!r}")
