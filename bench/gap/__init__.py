"""Sim-to-real gap diagnosis (docs/GAP.md).

replay     re-runs the flight filter (fsw_bindings.NavUkf) over a log's IMU and
           pose streams with a candidate's corrections applied to the inputs
null       thresholds from a seeded Monte Carlo of simulated-on-simulated logs
localise   the gap map: stream, axis, regime, frequency and lag
candidates parametric models of the in-library effects, as the diagnoser sees them
attribute  cheap screening of every candidate, confirmation by full fits, ranking
quantify   train / held-out time blocks, deficit, shrink with bootstrap interval
report     Markdown page with plots
diagnose   the whole pipeline on one log (``proxops diagnose``)
validate   the blind campaign (``proxops validate-gap``)
"""
