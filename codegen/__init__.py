"""Bundle -> GLSL. numpy only: importing this never imports torch."""
from .network import FILTERS, OPTIONS, SHORTHANDS, STORAGE_MODES, TARGETS, TEXTURE_FORMATS, Generated, generate

__all__ = ["generate", "Generated", "TARGETS", "STORAGE_MODES", "FILTERS", "TEXTURE_FORMATS", "OPTIONS", "SHORTHANDS"]
