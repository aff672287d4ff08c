"""The ``rfsdf`` command: parses arguments, calls the library, turns bad input into one line.

One module per command group; importing them registers their commands on :data:`main`."""

from . import capture, data, reconstruct, scene, workflows  # noqa: F401  (registers the commands)
from .app import main
from .data import image_cmd

__all__ = ["main", "image_cmd"]
