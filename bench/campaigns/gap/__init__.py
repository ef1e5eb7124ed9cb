"""The campaigns that validate the gap diagnosis (bench/gap) and make its
committed data. They use the diagnosis; the diagnosis never uses them
(tests/py/test_architecture.py).

  validate             blind campaign of the bench inspector (``proxops validate-gap``)
  validate_mixtures    two or three effects at once (``--mixtures``)
  validate_vehicle     the 12 kg inspector's logs, and its flight family's null calibration
  validate_basilisk    the 12 kg campaign flown by Basilisk (``--engine basilisk``)
  validate_random      a vehicle drawn for every run (``--vehicle random``)
  validate_plans       the plan that separates an ambiguous answer, flown after its log (``--plans``)
  detectable           minimum detectable size of an effect in one run (the campaigns' sizes)
  separability         whether a run's data can tell its effect from each candidate (scoring)
  characterise         which manoeuvre tells thruster misalignment from thrust loss
  results_tables       Markdown tables of a campaign's JSON, as docs/results/ shows them
  perf_diagnose        wall time of one diagnosis of a 10-minute log
  null_calibration     the committed null calibrations (bench/gap/null.py), made again
  simlogs              the bench's docking scenario written as flight logs
  bundled_run          the bundled reality run (bench/gap/bundled.py), made again
  log_null_far         the calibration made for a log, checked: tail model, false alarms on random vehicles
"""
