"""Figures: one module per figure, each a pure function from data to a matplotlib Figure.

Every module exposes ``make(...) -> (Figure, dict)``: the figure and the numbers it shows
(the figure data), which the pipeline writes beside the PNG and the tests check against
references. :func:`bouncelab.figures.style.save_figure` writes both deterministically.
"""
