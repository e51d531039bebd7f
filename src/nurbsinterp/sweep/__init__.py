"""Sweeps (issue 31): many programs x machines x settings, each case planned and simulated where it lands.

:mod:`.spec` reads a sweep file and expands its cases; :mod:`.case` runs one case into its row.  Neither
imports Dask: the cluster that runs the cases is the caller's (docs/design/sweep.md).
"""
