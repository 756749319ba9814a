"""Typed errors of the impulse core."""


class FootoptError(Exception):
    """Base of every error footopt raises on purpose."""


class ModelError(FootoptError, ValueError):
    """A model or scene that cannot be evaluated; the message names the field and the problem."""


class NumericalError(FootoptError, ArithmeticError):
    """Valid values whose impact the solver cannot resolve in float64 (e.g. a rod 1e-300 m
    long): a failed evaluation to record, not a bad input."""
