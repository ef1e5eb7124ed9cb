"""Sim-to-real gap diagnosis (docs/GAP.md): one flight log in, where the
model and the log disagree, which unmodelled effect explains it, and how far
it shrinks on data the fit never saw.

The modules are the diagnosis's stages; diagnose.py calls them in order,
once each, and names what each hands to the next:

  1 load        load          the log resolved: LogData (its description, IMU ticks, poses, valves)
    thresholds  null, log_null  the null calibration the log is judged by (calibration_file: a
                              supplied one checked; validity: the envelope it was validated on)
  2 replay      replay        the flight filter re-run over the log, with a candidate's corrections
  3 channels    dyn           the dynamics channel: the IMU against the commanded valves
  4 map         detection, localise   the gap map and the two detection statistics
  5 screen      attribute, candidates  every in-library candidate on its linearised signature
  6 quantify    quantify      training and held-out blocks, shrink, held-out scores
  7 confirm     verdict, select, alternatives   full refits, sets, the verdict
    and select
  8 answer      answers       the answer as JSON and in words
  9 report      report, report_plots   the Markdown page with its figures

Beside them: design (``proxops plan``: the valve plan that tells apart the
sets a diagnosis could not) and bundled (the bundled reality run and its
sealed key). The campaigns that validate the diagnosis are in
bench/campaigns/gap; they use this package, never the reverse
(tests/py/test_architecture.py).
"""
