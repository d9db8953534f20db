"""The grid shapes of Figs. 2 and 3; they live in :mod:`stbs.shapes`, imported from here
as well for existing code."""

from ..shapes import bar, box, box_tets, cigar, sections

__all__ = ["cigar", "box", "bar", "sections", "box_tets"]
