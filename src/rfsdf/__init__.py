"""rfsdf: neural SDF reconstruction of geometry and materials from mmWave MIMO radar.

Layers, lowest first: ``geometry`` and ``materials`` -> ``mesh`` -> ``scene`` ->
``radar`` -> ``field`` -> ``recon`` -> ``metrics`` / ``viz`` -> ``cli``.
"""

__version__ = "0.1.0"
__all__ = ["__version__"]
