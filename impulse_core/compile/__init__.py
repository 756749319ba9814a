"""Compiled evaluation: C code per topology, the on-disk cache, batched evaluators."""
