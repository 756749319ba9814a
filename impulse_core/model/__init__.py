"""Designs and scenes as frozen dataclasses (Tree, Scene, Topology) and the ground profile."""
