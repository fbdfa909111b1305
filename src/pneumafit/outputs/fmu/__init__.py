"""The fitted plant as an FMI 2.0 co-simulation FMU (``pneumafit export --format fmu``).

>>> from pneumafit.outputs.fmu import build_fmu
>>> build_fmu(Path("fits/convection/fit.json"), Path("plant.fmu"))  # doctest: +SKIP
"""

from pneumafit.outputs.fmu.builder import (
    FMU_INPUTS,
    FmuBuildError,
    FmuVariable,
    build_fmu,
    c_code_digest,
    check_structure,
    find_compiler,
    fmu_variables,
    parts_header,
    write_fmu,
)

__all__ = [
    "FMU_INPUTS",
    "FmuBuildError",
    "FmuVariable",
    "build_fmu",
    "c_code_digest",
    "check_structure",
    "find_compiler",
    "fmu_variables",
    "parts_header",
    "write_fmu",
]
