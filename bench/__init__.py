"""Python bench for the inspector flight software: plant, sensors, scenarios,
metrics, plots, gap diagnosis and the `proxops` command line."""

__version__ = "0.1.0"
