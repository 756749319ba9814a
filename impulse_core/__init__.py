"""footopt's impulse core: a differentiable model of a floating tree's impact (CasADi + numpy)."""
