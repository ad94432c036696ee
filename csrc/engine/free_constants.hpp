// The engine tolerances the free-body code reads (rotation, integrators, exact flow). Their one
// home is rblog/engine/constants.py: the values are read from it when rblog.engine._core is
// imported (load_free_constants, bind_free.cpp), never written here a second time.
#pragma once

namespace rb {

struct FreeConstants {
    double polar_tol = 0.0;                  // constants.POLAR_TOL
    int polar_max_iter = 0;                  // constants.POLAR_MAX_ITER
    double max_rotation_per_step_rad = 0.0;  // constants.MAX_ROTATION_PER_STEP_RAD
    double landen_base_parameter = 0.0;      // constants.LANDEN_BASE_PARAMETER
    int landen_max_levels = 0;               // constants.LANDEN_MAX_LEVELS (<= 12: N_FLOW's mu slots)
    double carlson_series_tol = 0.0;         // constants.CARLSON_SERIES_TOL
};

// Filled once at import (bind_free.cpp); read-only afterwards.
extern FreeConstants free_constants;

}  // namespace rb
