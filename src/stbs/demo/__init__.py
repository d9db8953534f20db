"""The demo: the paper's Figs. 2 and 3 on shapes generated in code (no input files).

``run_demo(out_dir)`` is what ``stbs demo`` runs; :mod:`stbs.demo.figures` has one
function per figure returning meshes and numbers; :mod:`stbs.demo.shapes` the
built-in shapes (cigar, box, two-bone bar).
"""

from .figures import (
    FIGURES,
    Figure,
    fig2_cigar_stretch,
    fig3_bar_bend_twist,
    fig3_box_twist,
)
from .run import DemoResult, format_summary, run_demo
from .shapes import bar, box, cigar

__all__ = ["run_demo", "DemoResult", "format_summary", "Figure", "FIGURES",
           "fig2_cigar_stretch", "fig3_box_twist", "fig3_bar_bend_twist", "cigar", "box", "bar"]
