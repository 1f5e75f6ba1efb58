"""Scenes: TOML files validated by pydantic models, and builders turning them into engine objects."""

from magsoro.scene.load import format_validation_error, load_scene, parse_scene
from magsoro.scene.schema import Scene
from magsoro.scene.write import write_scene

__all__ = ["Scene", "load_scene", "parse_scene", "format_validation_error", "write_scene"]
