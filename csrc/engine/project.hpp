// The project stage (project.cpp, whose header has the derivation; bound as
// _core.apply_projection): a nonlinear position pass on fresh contact geometry after the drift,
// stage(settings, bodies, state, scratch) over the world step's records (records.hpp) and the
// pass's own points (manifold.hpp ProjectPoint).
#pragma once

#include <cstddef>

#include <vector>

#include "common/array.hpp"
#include "engine/collision.hpp"
#include "engine/records.hpp"

namespace rb {

// Gather the points around those deeper than cfg.projection_depth at the end-of-step poses x and
// push them out (project.cpp). pairs (K, 2): the broadphase's shape pairs, the first n_pairs
// used. Fills sc.proj_points and sc.proj_dx / sc.proj_dth (N+1, 3: each gathered body's
// correction); work arrays sc.ring, sc.done, sc.cb. Returns the number of points, 0 when nothing
// is deeper than the depth. mf, keys, idx, n_man: this step's manifolds, sorted by key
// (sort_manifolds); their normals let the first pass pass over pairs parted along them.
i64 project_positions(const Settings& cfg, const Bodies& bd, const Statics& st, V1<i64> awake,
                      const BodyState& x, V2<i64> pairs, i64 n_pairs, V1<Manifold> mf,
                      V1<i64> keys, V1<i64> idx, i64 n_man, Scratch& sc);

// Move the bodies of points by their corrections dx / dth (N+1, 3); x's rows change in place.
void apply_projection(V1<ProjectPoint> points, V2<double> dx, V2<double> dth, int method,
                      int ortho, const Bodies& bd, bool iso_shortcut, const BodyState& x,
                      V2<double> l_scratch, V1<i64> anchor_steps);

}  // namespace rb
