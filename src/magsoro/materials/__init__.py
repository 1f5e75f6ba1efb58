"""Material library (silicone / NdFeB composites with sources) and mixture rules."""

from magsoro.materials.library import (
    NDFEB_DENSITY,
    NDFEB_REMANENCE,
    MaterialEntry,
    MaterialLibraryError,
    builtin_library,
    get_material,
    load_library,
    mixture_density,
    ndfeb_volume_fraction,
)

__all__ = [
    "NDFEB_DENSITY", "NDFEB_REMANENCE", "MaterialEntry", "MaterialLibraryError", "builtin_library", "get_material",
    "load_library", "mixture_density", "ndfeb_volume_fraction",
]
