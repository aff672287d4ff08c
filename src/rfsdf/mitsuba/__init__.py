"""Scenes of the radio ecosystem: Sionna RT's Mitsuba 3 XML files, read as rfsdf scenes and
written from them."""

from .read import is_xml_file, read_mitsuba_scene

__all__ = ["is_xml_file", "read_mitsuba_scene"]
