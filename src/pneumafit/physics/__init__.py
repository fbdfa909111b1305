"""Physics layer: pure scalar functions in SI units (no I/O, no state).

Every function here is compiled with numba (``cache=True``) so that the model
layer can compose them inside the compiled right-hand side; each one is also an
ordinary Python function (``f.py_func``) for tests and reference solvers.
"""

from pneumafit.physics import air, friction, geometry, heat, valve, valve_map

__all__ = ["air", "friction", "geometry", "heat", "valve", "valve_map"]
