"""sim's exceptions: one tree under SimError, messages built from the facts."""

from __future__ import annotations

import inspect

import pytest

from sim import errors
from sim.config import BeamConfig
from sim.errors import (
    IntegrationError,
    ModelNotAvailable,
    SimError,
    SimInputError,
    SolverError,
    StaticSolveError,
)


def test_every_exception_of_sim_is_a_sim_error() -> None:
    classes = [
        c for _, c in inspect.getmembers(errors, inspect.isclass) if c.__module__ == errors.__name__
    ]
    assert {c.__name__ for c in classes} >= {"SimInputError", "IntegrationError", "SolverError"}
    assert all(issubclass(c, SimError) for c in classes)


def test_input_errors_are_value_errors_naming_the_parameter() -> None:
    with pytest.raises(SimInputError) as info:
        BeamConfig(length_m=-1.0)
    assert isinstance(info.value, ValueError)
    assert info.value.parameter == "length_m"
    assert str(info.value) == "length_m must be a positive finite number, got -1.0"


def test_constructors_build_the_sentence() -> None:
    assert str(IntegrationError("BDF", 0.25, "step size underflows")) == (
        "BDF integration failed at t = 0.25 s: step size underflows"
    )
    assert str(StaticSolveError("Newton did not converge", 2, 5)) == (
        "static solve: Newton did not converge at load step 2/5"
    )
    assert str(SolverError("linear Radau IIA", "no convergence")) == (
        "linear Radau IIA: no convergence"
    )
    assert str(ModelNotAvailable("fe", "free-decay", "modal only")) == (
        "the free-decay scene does not run the fe model (modal only)"
    )
