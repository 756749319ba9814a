"""One spatial kinematic core (planar = its restriction to z axes) and the multibody dynamics over it."""
