"""The names the job files, the library and the CLI share, in one place.

A new interpolation method, profile type, block kind or axis is named here once;
validation, the kernels' codes, the CLI's choices and the reports all read it.
"""

METHODS = ("taylor1", "taylor2", "rk4", "exact")  # the real-time interpolators (docs/interpolation.md)
SHAPES = ("trapezoidal", "exponential", "bell")  # the paper's ramp profiles (Section 3)
PROFILE_TYPES = (*SHAPES, "adaptive")  # adaptive: the limit-aware planner (planner package)
ACCDEC = ("before", "after")  # acc/dec before interpolation (the paper's) or after it (the conventional one)
AXES = ("x", "y", "z")
BLOCK_KINDS = ("line", "arc", "nurbs")  # the blocks of a path (config.path, path.py)
PRECOMPENSATION = ("exact", "zpetc", "match")  # the servo-lag pre-compensators (precompensate.py)
ROUNDINGS = ("nearest", "shaped")  # --resolution: plain rounding, or first-order noise shaping (quantise.py)
