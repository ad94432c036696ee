// The contact step's stages and world_advance (world_step.cpp; rblog/engine/contact/step.py).
// Each stage is a function of the model records (bd, st, cfg), the state record (x) and the work
// arrays (sc), callable on its own (bind_contact.cpp binds them for the tests); world_advance
// calls them in step order.
#pragma once

#include <cstddef>

#include <utility>

#include "common/array.hpp"
#include "engine/collision.hpp"
#include "engine/impulses.hpp"
#include "engine/records.hpp"

namespace rb {

// step.py's ST_* indices into the stats array the step accumulates (their home: step.py, which
// checks them against _core.ST_NAMES at import).
enum StatIndex : int {
    ST_STEPS = 0, ST_PAIRS, ST_MANIFOLDS, ST_POINTS, ST_AWAKE, ST_IMPACTS, ST_WOKEN, ST_SLEPT,
    ST_SWEEPS, ST_PROJECTED, N_STATS
};

// rblog.contract.trajectory's contact kinds (their home; step.py checks them at import).
constexpr i64 CONTACT_RESTING = 0;
constexpr i64 CONTACT_IMPACT = 1;

namespace step {

void kick(const Bodies& bd, V1<i64> awake, const BodyState& x, double h);
i64 broadphase(const Bodies& bd, const Statics& st, double margin, V1<i64> awake,
               const BodyState& x, double h, Scratch& sc, Buf2<i64>& pairs);
i64 wake(const Bodies& bd, const Statics& st, const Settings& cfg, const SleepState& sl,
         const BodyState& x, double h, Scratch& sc, V2<i64> pairs, i64 n_pairs);
CollideCount collide(const Bodies& bd, const Statics& st, const Settings& cfg, V1<i64> awake,
                     const BodyState& x, Scratch& sc, V2<i64> pairs, i64 n_pairs,
                     ContactCache& c);
void prepare(const Bodies& bd, const Settings& cfg, const BodyState& x, Scratch& sc,
             V1<ManifoldHead> mi,
             V1<Manifold> mf, V1<ContactPoint> pf, i64 n_man, double h);
void mark_pushed(V1<ManifoldHead> mi, V1<ContactPoint> pf, i64 n_man, i64 n, Scratch& sc);
void mark_exact(const Settings& cfg, V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf,
                i64 n_man, i64 n,
                Scratch& sc);
// What stage 9's exact motion reads (world_step.cpp, "Exact motion on one static surface"): this
// step's manifolds, and the previous step's (sorted by key, ContactCache's mf0, keys0, idx0,
// n_man0) for whether a pair's anchor was held over from it.
struct ExactInputs {
    ContactConstraints now;
    V1<Manifold> prev_mf;
    V1<i64> prev_keys, prev_idx;
    i64 prev_n = 0;
};
// exact: when mark_exact sorted the bodies (sc.exact_man), else null (every pushed body by
// symplectic Euler)
void integrate_positions(int method, int ortho, const Bodies& bd, const Settings& cfg,
                         V1<i64> awake, const BodyState& x, Scratch& sc, double h,
                         const FlowAnchors& an, const ExactInputs* exact = nullptr);
// mf, keys, idx, n_man: this step's manifolds, sorted by key (project_positions)
i64 project(int method, int ortho, const Bodies& bd, const Statics& st, const Settings& cfg,
            V1<i64> awake, const BodyState& x, Scratch& sc, V2<i64> pairs, i64 n_pairs,
            V1<Manifold> mf, V1<i64> keys, V1<i64> idx, i64 n_man, const FlowAnchors& an);
std::pair<i64, i64> sleep_stage(const Bodies& bd, const Settings& cfg, const SleepState& sl,
                                const BodyState& x, Scratch& sc, V1<ManifoldHead> mi,
                                V1<Manifold> mf, V1<ContactPoint> pf, i64 n_man, double h,
                                i64 n_awake);
i64 soft_stages(const Bodies& bd, const Settings& cfg, const BodyState& x, Scratch& sc,
                V1<i64> awake, V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf,
                i64 n_man, int method, int ortho, double h, const FlowAnchors& an, V1<i64> prof,
                i64& t);
i64 first_diverged(V1<i64> awake, const BodyState& x, V2<double> inv_inertia, double h);
i64 record_contacts(i64 s, V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf, i64 n_man,
                    V2<double> position, V3<double> rotation, V2<double> pose0,
                    Buf2<i64>& log_i, Buf2<double>& log_f, i64 n_log);

}  // namespace step

struct AdvanceResult {
    i64 n_samples, bad_step, bad_body, n_log;
};

AdvanceResult world_advance(const Bodies& bd, const Statics& st, const Settings& cfg, int method,
                            int ortho, double dt, i64 n_steps, i64 stride, bool sample_last,
                            const BodyState& x, const SampleState& out, const SleepState& sl,
                            ContactCache& c, V1<i64> stats, V1<i64> prof, const FlowAnchors& an,
                            const IntervalImpulses& im);

}  // namespace rb
