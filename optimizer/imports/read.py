"""A robot description file read by its format: URDF (``<robot>``) or MJCF (``<mujoco>``)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from optimizer.config.model_file import read_text
from optimizer.errors import ConfigError
from optimizer.imports.description import Description, check_xml_safe
from optimizer.imports.mjcf import read_mjcf
from optimizer.imports.urdf import read_urdf


def read_description(path: Path) -> Description:
    """The description in ``path``, by its root element: ``<robot>`` URDF, ``<mujoco>`` MJCF."""
    text = read_text(path, "robot description")
    check_xml_safe(text, path)
    try:
        tag = ET.fromstring(text).tag
    except ET.ParseError as e:
        raise ConfigError(f"not well-formed XML: {e}", path) from None
    if tag == "robot":
        return read_urdf(path, text)
    if tag == "mujoco":
        return read_mjcf(path)
    raise ConfigError(f"the root element is <{tag}>: neither URDF (<robot>) nor MJCF (<mujoco>)", path)


__all__ = ["read_description"]
