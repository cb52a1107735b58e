"""Measurement specifications: what to measure, where, nominal and tolerance."""

from ita.specs.model import MeasurementKind, MeasurementSpec, Tool

__all__ = ["MeasurementKind", "MeasurementSpec", "Tool"]
