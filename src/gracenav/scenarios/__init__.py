"""Scenario files: parsing and checks, running a scenario's starts with the hybrid
controller or the decoupled baseline, summaries and outputs.
"""

from gracenav.scenarios.outputs import (
    summary_dict,
    write_outputs,
)
from gracenav.scenarios.run import (
    PreparedLibrary,
    check_task,
    library_key,
    prepare_library,
    run_scenario,
)
from gracenav.scenarios.runs import (
    RunSummary,
    ScenarioResult,
)
from gracenav.scenarios.spec import (
    MAX_INSTANTIATIONS,
    PLANNERS,
    PLANT_FACTOR_FIELDS,
    PLANT_FACTOR_RANGE,
    Scenario,
    apply_plant_factors,
    check_scenario,
    estimate_instantiations,
    load_scenario,
    load_scenario_map,
    parse_scenario,
)

__all__ = [
    "MAX_INSTANTIATIONS",
    "PLANNERS",
    "PLANT_FACTOR_FIELDS",
    "PLANT_FACTOR_RANGE",
    "PreparedLibrary",
    "RunSummary",
    "Scenario",
    "ScenarioResult",
    "apply_plant_factors",
    "check_scenario",
    "check_task",
    "estimate_instantiations",
    "library_key",
    "load_scenario",
    "load_scenario_map",
    "parse_scenario",
    "prepare_library",
    "run_scenario",
    "summary_dict",
    "write_outputs",
]
