"""Coordinate frames: WGS-84 geodesy, the stereographic system plane, local NED/ENU,
and conversion of radar plots (with covariance) into the system frame.

Tracker coordinates are x east, y north, z up in every frame kind (see
:mod:`fusion.frames.system_frame`). The one call the tracker and services use is
:func:`convert_plots`.
"""

from .plot_conversion import ConvertedPlots, convert_plots
from .stereographic import Stereographic
from .system_frame import SystemFrame

__all__ = ["ConvertedPlots", "Stereographic", "SystemFrame", "convert_plots"]
