"""Rendering only: self-contained HTML reports, maps, plots and route exports."""
