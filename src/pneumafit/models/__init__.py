"""Model layer: parameter and state layouts, physics parts, structures, compiled kernel."""

from pneumafit.models.layout import CHANNELS, PARAMETER_NAMES, PARAMETER_SPECS, ParameterSpec
from pneumafit.models.parameters import default_parameters, parameter_dict, parameter_vector
from pneumafit.models.parts import Friction, Model, Valve
from pneumafit.models.structure import EFFECT_SLOTS, MODELS, ModelStructure, get_structure

__all__ = [
    "CHANNELS",
    "EFFECT_SLOTS",
    "MODELS",
    "PARAMETER_NAMES",
    "PARAMETER_SPECS",
    "Friction",
    "Model",
    "ModelStructure",
    "ParameterSpec",
    "Valve",
    "default_parameters",
    "get_structure",
    "parameter_dict",
    "parameter_vector",
]
