"""Studies: workflows over the library packages, run by the command line and the benchmarks.

A study composes what the library offers (databases, training, the REV, the comparison, the
cell solvers) into one job with its own outputs, and nothing in the library imports it back:
:mod:`~hmodel.studies.reproduce` (``hmodel reproduce``: the whole study as one HTML report),
:mod:`~hmodel.studies.sweep` (``hmodel surrogate sweep``: the report's Table 2.1) and
:mod:`~hmodel.studies.refine` (``hmodel surrogate refine``: active learning of a learned cell).
The import-linter layers contract of ``pyproject.toml`` places this package directly below
:mod:`hmodel.cli`.
"""
