"""Neural fields: positional encoding, the geometry (SDF) network, the reflectivity network, the material head, a coarse displacement."""

from .displacement import KnotDisplacement
from .encoding import PositionalEncoding, levels_for
from .networks import MaterialHead, RadarField, ReflectivityNetwork, SDFNetwork

__all__ = ["PositionalEncoding", "levels_for", "SDFNetwork", "ReflectivityNetwork", "MaterialHead", "RadarField",
           "KnotDisplacement"]
