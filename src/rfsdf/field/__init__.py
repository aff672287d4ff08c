"""Neural fields: positional encoding, the geometry (SDF) network, the reflectivity network."""

from .encoding import PositionalEncoding, levels_for
from .networks import RadarField, ReflectivityNetwork, SDFNetwork

__all__ = ["PositionalEncoding", "levels_for", "SDFNetwork", "ReflectivityNetwork", "RadarField"]
