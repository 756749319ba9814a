"""Bridges to independent peers (Pinocchio, MuJoCo), imported lazily by tests, bench and drop."""
