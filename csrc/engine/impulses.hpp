// The per-interval contact impulses of the log contract (v3; docs/log-format.md): what the
// contact stages gave each body, summed over the steps between two samples (impulses.cpp).
#pragma once

#include <nanobind/nanobind.h>

#include "common/array.hpp"
#include "engine/records.hpp"

namespace rb {

// The accumulators world_advance keeps across steps and calls (rblog.engine.contact.world
// holds the arrays, so an interval may span compiled calls). Empty views (acc.n0 == 0): off.
//   acc    (N, 6)  contact impulse since the last sample: linear (N s), angular about the
//                  centre of mass (N m s), world frame
//   start  (N, 6)  P and L after this step's kick (the contact stages' starting momenta)
//   kicked (N,)    1: the body was awake at the kick (it received h (m g + F), h tau)
//   out    (S, N, 6) the sample buffers: acc at each sample, then acc = 0
struct IntervalImpulses {
    V2<double> acc;
    V2<double> start;
    V1<i64> kicked;
    V3<double> out;
    bool on() const { return acc.n0 > 0; }
    static IntervalImpulses from_py(nanobind::handle r);  // no `acc` attribute: off
};

namespace step {

// After the kick (stage 1): the momenta the contact stages start from, and who was kicked.
void impulses_begin(V1<i64> awake, const BodyState& x, const IntervalImpulses& im);
// At the end of a step (stepped: the step ran; a step of sleeping bodies only does not):
// acc += (P, L) - start for the bodies that were kicked; a body that was not (asleep) received
// neither the kick nor, in the stages, the support of its resting contacts, and its contact
// impulse is that support: -h (m g + F), -h tau (bd.force, bd.torque), which holds it still.
void impulses_end(const Bodies& bd, const BodyState& x, double h, bool stepped,
                  const IntervalImpulses& im);
// At sample `sample`: out[sample] = acc, acc = 0.
void impulses_sample(const IntervalImpulses& im, i64 sample);

}  // namespace step
}  // namespace rb
