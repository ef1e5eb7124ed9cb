"""Performance comparisons: the flight code's cost beside reference
implementations (blr_numpy, modal_numpy, FilterPy), the HIL loop's real-time
factor, and what the campaign runner costs (perf_*)."""
