"""Typed errors of the impulse core."""


class FootoptError(Exception):
    """Base of every error footopt raises on purpose."""


class ModelError(FootoptError, ValueError):
    """A model or scene that cannot be evaluated; the message names the field and the problem."""
