"""Wear of clearance joints (Archard's law on the hybrid model's contact field) and the
profile it leaves: :func:`wear` runs windows, wears the bearing, runs the next window on the
worn profile."""

from .archard import WindowWear, deposit, point_wear_rates, wear_element, window_wear
from .figures import plot_wear
from .profile import bearing_deviation, fourier_of_nodes, node_angles, prepare, worn
from .service import WearHistory, WearOptions, wear

__all__ = ["WearHistory", "WearOptions", "WindowWear", "bearing_deviation", "deposit", "fourier_of_nodes",
           "node_angles", "plot_wear", "point_wear_rates", "prepare", "wear", "wear_element", "window_wear", "worn"]
