"""The search box, as the fitting stage names it: every name of `brdfjax.models.bounds`.

The box and its transforms are defined in the models layer (`brdfjax.models.bounds`), where a
model's own code uses them without importing the fitting stage; they are re-exported here
for code that imports them from ``brdfjax.fitting.bounds``.
"""

from brdfjax.models.bounds import (
    ASINH,
    LINEAR,
    LOG10,
    SATURATED,
    SCALES,
    Bounds,
    default_bounds,
    from_free,
    from_unit,
    make_bounds,
    scale_label,
    scaled,
    to_free,
    to_unit,
)

__all__ = ["ASINH", "LINEAR", "LOG10", "SATURATED", "SCALES", "Bounds", "default_bounds",
           "from_free", "from_unit", "make_bounds", "scale_label", "scaled", "to_free", "to_unit"]
