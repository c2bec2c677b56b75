"""Bundle -> GLSL. numpy only: importing this never imports torch."""
from .network import FILTERS, STORAGE_MODES, TARGETS, Generated, generate

__all__ = ["generate", "Generated", "TARGETS", "STORAGE_MODES", "FILTERS"]
