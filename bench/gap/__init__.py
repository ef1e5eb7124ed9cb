"""Sim-to-real gap diagnosis (docs/GAP.md).

In layers, top to bottom (a module imports its own layer or lower ones;
tests/py/test_architecture.py checks it):

campaigns
  validate, validate_vehicle, validate_mixtures   blind campaigns (``proxops validate-gap``)
  detectable, separability, characterise          detection limits, what the data can tell apart
  design      the test that separates: a valve plan for sets a log cannot tell apart
  bundled, perf_diagnose, results_tables          the bundled run, timing, tables for docs/
the answer
  diagnose    the whole pipeline on one log (``proxops diagnose``): verdict, set, shares
  answers     the answer in words, one text for the command line and the report
  report      Markdown page with plots
  report_plots  its figures: the gap map, residuals and their spectra
null calibrations
  null        the committed thresholds (seeded Monte Carlo of simulated-on-simulated logs)
  log_null    a calibration made for a log (parametric bootstrap of its own flight)
  simlogs     simulated logs of the docking scenario (runs go through bench/runner)
  calibration_file  what a --calibration file must hold before its thresholds are trusted
  validity    the envelope the diagnosis is validated on; a log outside it, named
the model
  detection   the two detection statistics under the nominal model
  select      several effects at once: forward selection and joint refit
  alternatives  the sets the data cannot tell from the answer's: look-alikes, sets
                that explain as well, hidden members
  attribute   screening of every candidate, confirmation by full fits, Bayes factors
  localise    the gap map: stream, axis, regime, frequency and lag
  quantify    train / held-out time blocks, deficit, shrink with bootstrap interval
  dyn         the dynamics channel: accelerometer and gyro against the valve commands
  candidates  parametric models of the in-library effects, as the diagnoser sees them
  replay      re-runs the flight filter (fsw_bindings.NavUkf) over a log's IMU and
              pose streams with a candidate's corrections applied to the inputs
"""
