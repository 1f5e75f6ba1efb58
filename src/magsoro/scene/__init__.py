"""Scenes: TOML files validated by pydantic models, and builders turning them into engine objects."""

from magsoro.scene.load import format_validation_error, load_scene, parse_scene
from magsoro.scene.schema import Scene

__all__ = ["Scene", "load_scene", "parse_scene", "format_validation_error"]
