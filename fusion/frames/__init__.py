"""Coordinate frames: WGS-84 geodesy, the stereographic system plane, local NED/ENU,
and conversion of radar plots (with covariance) into the system frame."""

from .stereographic import Stereographic

__all__ = ["Stereographic"]
