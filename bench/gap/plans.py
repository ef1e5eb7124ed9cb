"""The manoeuvre plans live in bench/sim/plans.py, beside the simulation that
flies them. This module only names them again for
bench/gap/validate_mixtures.py, which still imports ``then_scripts`` from
here; it goes once that import names bench.sim.plans."""

from bench.sim.plans import (  # noqa: F401
    CHARACTERISATION_COAST_S,
    CHARACTERISATION_FIRE_S,
    DT_S,
    LEAD_S,
    MANOEUVRES,
    characterisation_plan,
    scripts_duration_s,
    single_valve_scripts,
    then_scripts,
)
