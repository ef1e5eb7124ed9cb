"""Campaign machinery: every Monte Carlo, null calibration and blind
validation runs its runs as Dask tasks (a local cluster by default, or an
existing one), each run's result written to a results store on disk as soon
as it finishes, so a campaign resumes where it stopped and its summary can
be recomputed from the store (docs/CAMPAIGNS.md)."""
