"""Python bench for the inspector flight software, in packages by role:
sim (the simulation models), campaigns (seeded studies of the flight code),
perf (performance comparisons), gap (the sim-to-real gap diagnosis), runner
(the campaign runner and its results store), commands and cli (the
`proxops` command line); so3 and report are shared by all of them. The
rules between them: docs/ARCHITECTURE.md."""

__version__ = "0.1.0"
