"""The demo: the paper's figures on shapes generated in code (no input files).

``run_demo(out_dir)`` is what ``stbs demo`` runs. :mod:`stbs.demo.figures` (Figs. 2,
3) and :mod:`stbs.demo.paper` (Figs. 4-12) have one function per figure returning
meshes, numbers and what to draw; the shapes come from :mod:`stbs.shapes` (the
library's generators) and :mod:`stbs.demo.models` (the demo's own models, built
from them); :mod:`stbs.demo.render` draws headless PNG/GIF with matplotlib and
:mod:`stbs.demo.gallery` writes ``index.html``.
"""

from .figures import (
    FIGURES,
    Figure,
    fig2_cigar_stretch,
    fig3_bar_bend_twist,
    fig3_box_twist,
)
from .run import FIGURE_KEYS, DemoResult, format_summary, run_demo

__all__ = ["run_demo", "DemoResult", "format_summary", "Figure", "FIGURES", "FIGURE_KEYS",
           "fig2_cigar_stretch", "fig3_box_twist", "fig3_bar_bend_twist"]
