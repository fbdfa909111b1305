"""Simulation layer: experiments, compiled fixed-step simulator, reference solver."""

from pneumafit.simulation.experiment import PD, Experiment, StateFeedback
from pneumafit.simulation.sampled import simulate_sampled
from pneumafit.simulation.simulator import (
    DEFAULT_STEP,
    AirConsumption,
    PackedExperiments,
    Simulation,
    Simulator,
    choose_step,
    spool_lag,
    spool_mode,
    substeps,
)
from pneumafit.simulation.tableau import DP5, HEUN, KUTTA3, RK4, Tableau

__all__ = [
    "DEFAULT_STEP",
    "DP5",
    "HEUN",
    "KUTTA3",
    "PD",
    "RK4",
    "AirConsumption",
    "Experiment",
    "PackedExperiments",
    "Simulation",
    "Simulator",
    "StateFeedback",
    "Tableau",
    "choose_step",
    "simulate_sampled",
    "spool_lag",
    "spool_mode",
    "substeps",
]
