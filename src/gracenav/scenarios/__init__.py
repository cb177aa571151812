"""Scenario files: parsing and checks, the memory budget, running a scenario's starts
with the hybrid controller or the decoupled baseline, summaries and outputs.
"""

from gracenav.scenarios.budget import (
    DEFAULT_MAX_HALVINGS,
    DEFAULT_MEMORY_LIMIT_GIB,
    MAX_MEMORY_LIMIT_GIB,
    MemoryEstimate,
    choose_halvings,
    estimate_run_memory,
)
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
    PLANNERS,
    PLANT_FACTOR_FIELDS,
    PLANT_FACTOR_RANGE,
    Scenario,
    apply_plant_factors,
    check_scenario,
    load_scenario,
    load_scenario_map,
    parse_scenario,
)

__all__ = [
    "DEFAULT_MAX_HALVINGS",
    "DEFAULT_MEMORY_LIMIT_GIB",
    "MAX_MEMORY_LIMIT_GIB",
    "PLANNERS",
    "PLANT_FACTOR_FIELDS",
    "PLANT_FACTOR_RANGE",
    "MemoryEstimate",
    "PreparedLibrary",
    "RunSummary",
    "Scenario",
    "ScenarioResult",
    "apply_plant_factors",
    "check_scenario",
    "check_task",
    "choose_halvings",
    "estimate_run_memory",
    "library_key",
    "load_scenario",
    "load_scenario_map",
    "parse_scenario",
    "prepare_library",
    "run_scenario",
    "summary_dict",
    "write_outputs",
]
