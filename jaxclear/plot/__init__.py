"""Figures: :mod:`jaxclear.plot.figures` (a run's time series and orbits, sweeps' heat maps and
bifurcation diagrams, Poincare sections, fits; the shared style: ``COLORS``, ``new_figure``,
``save_figure``, ``abscissa``, ...), :mod:`jaxclear.plot.drawing` (drawings and animations of a
mechanism: ``plot_mechanism``, ``animate``) and :mod:`jaxclear.plot.profiles` (the time profiles of a
mechanism file, for ``jaxclear check``). What ``jaxclear.plot`` exports is the figures module's
``__all__`` (``jc.plot.plot_simulation(...)``, as before the package)."""

from .figures import (COLORS, DPI, FIGSIZE, abscissa, angle_ticks, clearance_region, joint_label, law_label,
                      new_figure, plot_bifurcation, plot_channel, plot_contact_force, plot_fit, plot_heatmap,
                      plot_orbit, plot_poincare, plot_profiles, plot_simulation, plot_slider_acceleration,
                      save_figure)
from . import drawing, profiles

__all__ = ["COLORS", "DPI", "FIGSIZE", "abscissa", "angle_ticks", "clearance_region", "joint_label", "law_label",
           "new_figure", "plot_bifurcation", "plot_channel", "plot_contact_force", "plot_fit", "plot_heatmap",
           "plot_orbit", "plot_poincare", "plot_profiles", "plot_simulation", "plot_slider_acceleration", "save_figure",
           "drawing", "profiles"]
