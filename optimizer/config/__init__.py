"""Validated, frozen configuration: model files and study files."""
