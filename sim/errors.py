"""The simulator's exceptions: one small tree rooted in :class:`SimError`, each message built
by the constructor from the facts.

- :class:`SimInputError`, also a ``ValueError``: an argument or configuration value that sim
  cannot use; the message starts with the parameter's name.
- :class:`ModelNotAvailable`: a model sim knows that a scene does not run.
- :class:`IntegrationError`: a time integrator failed (step size underflow, a non-finite
  state, too many steps).
- :class:`SolverError`: the batched linear Radau IIA (or the nonlinear modal iteration on it)
  did not reach its tolerance.
- :class:`StaticSolveError`: Newton's method did not converge for a static load step.

A caller that reports errors (the ``beambench`` command line) catches :class:`SimError` once.
"""

from __future__ import annotations


class SimError(Exception):
    """Base class of every error raised by ``sim``."""


class SimInputError(SimError, ValueError):
    """An input sim cannot use, e.g. ``mass_kg must be a non-negative finite number, got -1``.

    A ``ValueError`` too, so callers that validate with ``except ValueError`` (the rig loader)
    keep working.
    """

    def __init__(self, parameter: str, problem: str) -> None:
        self.parameter = parameter
        self.problem = problem
        super().__init__(f"{parameter} {problem}")


class ModelNotAvailable(SimError):
    """A model sim knows, which the scene does not run (rather than substituting another)."""

    def __init__(self, model: str, scene: str, reason: str) -> None:
        self.model = model
        self.scene = scene
        super().__init__(f"the {scene} scene does not run the {model} model ({reason})")


class IntegrationError(SimError):
    """The time integrator failed (step size underflow, non-finite state, ...)."""

    def __init__(self, method: str, t_s: float, problem: str) -> None:
        self.method = method
        self.t_s = t_s
        super().__init__(f"{method} integration failed at t = {t_s:.6g} s: {problem}")


class SolverError(SimError):
    """The linear Radau IIA solve did not reach the requested tolerance, or gave non-finite
    values (never a silently wrong answer)."""

    def __init__(self, solver: str, problem: str) -> None:
        self.solver = solver
        super().__init__(f"{solver}: {problem}")


class StaticSolveError(SimError):
    """Newton's method did not converge for a static load step."""

    def __init__(self, problem: str, load_step: int, n_load_steps: int) -> None:
        self.load_step = load_step
        self.n_load_steps = n_load_steps
        super().__init__(f"static solve: {problem} at load step {load_step}/{n_load_steps}")
