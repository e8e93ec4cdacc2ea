"""Presentation layer: text tables now; figures and HTML reports draw with matplotlib here only."""
