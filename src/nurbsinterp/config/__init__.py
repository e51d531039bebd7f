"""Reading and validating jobs: everything a user can get wrong is checked here, at the boundary.

- :mod:`.units`: numbers and quantities with units ("6000 mm/min", "1 us");
- :mod:`.reading`: safe YAML (no aliases, no duplicate keys, a size limit);
- :mod:`.rules`: :class:`Where` (the source of each field) and the field checks every reader uses;
- :mod:`.curve`: one NURBS (`curve:`, a path's `nurbs:` block);
- :mod:`.path`: a toolpath of line, arc and nurbs blocks (`path:`);
- :mod:`.job`: profile, interpolator and the frozen :class:`Job`; :func:`load_job`;
- :mod:`.readers`: the readers of job files, chosen by suffix.

Each violated rule raises a :class:`~nurbsinterp.errors.SpecError` whose message is one
line naming the source (file or option), the field, the index and the value::

    circle.yaml: curve.knots[4] = 0.3 is smaller than curve.knots[3] = 0.5
"""
from .curve import (MAX_COORDINATE, MAX_DEGREE, MAX_U_RESOLUTION, MAX_WEIGHT, MAX_WEIGHT_RATIO, MIN_WEIGHT,
                    CurveSpec, validate_curve)
from .job import (AXIS_LIMITS, ECHOED_FIELDS, LIMIT_FIELDS, SECTION_KEYS, InterpolatorSpec, Job, ProfileSpec,
                  load_job, validate_interpolator, validate_profile)
from .path import ArcBlock, LineBlock, NurbsBlock, PathSpec, path_of_curve, validate_path
from .reading import MAX_FILE_BYTES, read_yaml
from .rules import MAX_CONTROL_POINTS, Where, choice, finite, integer, mapping, number_list, quantity
from .units import parse_quantity, show

__all__ = [name for name in dir() if not name.startswith("_")]
