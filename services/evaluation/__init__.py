"""Offline evaluation: recordings against truth or Mode-S labels, Monte Carlo, the demo report."""
