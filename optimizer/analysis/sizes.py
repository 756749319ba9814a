"""Constants of ``footopt bench`` that its command line needs, apart from :mod:`optimizer.analysis.bench`
(which imports the design space): ``footopt --help`` and ``evaluate`` load this, not the bench."""

#: Body counts of the scaling series (more toes and more segments per toe).
SCALING_SIZES = (5, 10, 20, 50, 100, 200)

__all__ = ["SCALING_SIZES"]
