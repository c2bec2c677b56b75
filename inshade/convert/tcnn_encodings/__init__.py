"""tiny-cuda-nn's encodings, one family per module, each registered by its otypes in
``TCNN_ENCODINGS`` (inshade.convert.registry): the parameter-free ones (``fixed``), the grids
(``grid``) and the composites (``composite``); a component folder's ``lowering.py`` adds its own
(components/one_blob: OneBlob)."""
from inshade.components import registry as component_registry

from .base import Encoding, lanes_of, lower_encoding, parse_encoding
from .composite import Composite
from .fixed import Empty, Frequency, Identity, SphericalHarmonics, TriangleWave
from .grid import GRID_HASHES, Grid, dense_default_scale

__all__ = ["Composite", "Empty", "Encoding", "Frequency", "GRID_HASHES", "Grid", "Identity",
           "SphericalHarmonics", "TriangleWave", "dense_default_scale", "lanes_of", "lower_encoding", "parse_encoding"]

component_registry.load("lowering")
