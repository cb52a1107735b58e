"""Sensor-facing value types and device interfaces (no simulator, no as-built truth)."""
