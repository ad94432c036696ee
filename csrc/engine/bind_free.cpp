// Bindings of the free-body kernels (free.cpp) and of the rotation / integrator / exact-flow
// functions the tests call directly; and the engine tolerances, read from
// rblog/engine/constants.py (their one home) when the module is imported.
#include "engine/bind.hpp"
#include "engine/free_constants.hpp"

namespace rb {
namespace nb = nanobind;

FreeConstants free_constants;

static void load_free_constants() {
    nb::module_ c = nb::module_::import_("rblog.engine.constants");
    free_constants.polar_tol = nb::cast<double>(c.attr("POLAR_TOL"));
    free_constants.polar_max_iter = nb::cast<int>(c.attr("POLAR_MAX_ITER"));
    free_constants.max_rotation_per_step_rad = nb::cast<double>(c.attr("MAX_ROTATION_PER_STEP_RAD"));
    free_constants.landen_base_parameter = nb::cast<double>(c.attr("LANDEN_BASE_PARAMETER"));
    free_constants.landen_max_levels = nb::cast<int>(c.attr("LANDEN_MAX_LEVELS"));
    free_constants.carlson_series_tol = nb::cast<double>(c.attr("CARLSON_SERIES_TOL"));
}

void bind_free(nb::module_& m) { load_free_constants(); (void)m; }
}  // namespace rb
