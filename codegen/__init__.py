"""Bundle -> shader code (GLSL for OpenGL and Vulkan, WGSL, HLSL, Slang). numpy only: importing this never
imports torch."""
from .network import (FILTERS, GL_TARGETS, OPENGL_STORAGE_MODES, OPTIONS, SHORTHANDS, STORAGE_MODES, TARGETS,
                      TEXTURE_FORMATS, Generated, generate)
from .limits import GL33_MINIMUMS, LimitError

__all__ = ["generate", "Generated", "TARGETS", "GL_TARGETS", "STORAGE_MODES", "OPENGL_STORAGE_MODES", "FILTERS", "TEXTURE_FORMATS", "OPTIONS", "SHORTHANDS",
           "LimitError", "GL33_MINIMUMS"]
