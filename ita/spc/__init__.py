"""Statistical process control across the serials of one design: the charts and their
rules (:mod:`~ita.spc.chart`), the series from the archive (:mod:`~ita.spc.series`)."""

from ita.spc.chart import Chart, Flag, Series, benjamini_hochberg, chart, chart_all
from ita.spc.series import SerialRun, design_series

__all__ = ["Chart", "Flag", "SerialRun", "Series", "benjamini_hochberg", "chart", "chart_all", "design_series"]
