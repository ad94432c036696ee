// The per-interval contact impulses of the log contract (v3): for each body, the momentum the
// contact stages of every step between two samples gave it.
//
// A step changes a body's momenta by its kick (stage 1: P += h (m g + F), L += h tau) and by the
// contact stages (2-12: the velocity solve, relax's orbital hand-back, integrate's momenta of
// pushed bodies, restitution, project's hand-back; soft_step's substeps, which take the kick
// back out and apply it a share at a time, net h (m g + F) to round-off). So, with P0, L0 the
// momenta after the kick,
//
//     J_contact(step) = P_end - P0,   K_contact(step) = L_end - L0   (world, L about the COM)
//
// and over an interval of n steps, P[i] - P[i-1] = sum J_contact + n h (m g + F) exactly up to
// the rounding of the sums (tests/engine/test_impulses.py measures it). A body asleep at the
// kick is neither kicked nor pushed: its contacts hold it, and their impulse is the support
// -h (m g + F), -h tau, so the same balance holds for it (its P does not change).
#include "engine/impulses.hpp"

#include "common/py.hpp"

namespace rb {

IntervalImpulses IntervalImpulses::from_py(nanobind::handle r) {
    IntervalImpulses im;
    if (!nanobind::hasattr(r, "acc")) return im;  // off (step.py passes () for None)
    im.acc = f2<double>(r, "acc");
    im.start = f2<double>(r, "start");
    im.kicked = f1<i64>(r, "kicked");
    im.out = f3<double>(r, "out");
    return im;
}

namespace step {

void impulses_begin(V1<i64> awake, const BodyState& x, const IntervalImpulses& im) {
    for (i64 i = 0; i < x.position.n0; ++i) {
        double* s = im.start.row(i);
        for (int k = 0; k < 3; ++k) {
            s[k] = x.linear_momentum(i, k);
            s[3 + k] = x.angular_momentum(i, k);
        }
        im.kicked[i] = awake[i] != 0;
    }
}

void impulses_end(const Bodies& bd, const BodyState& x, double h, bool stepped,
                  const IntervalImpulses& im) {
    for (i64 i = 0; i < x.position.n0; ++i) {
        double* a = im.acc.row(i);
        if (stepped) {  // what the contact stages did (to a woken body as well)
            const double* s = im.start.row(i);
            for (int k = 0; k < 3; ++k) {
                a[k] += x.linear_momentum(i, k) - s[k];
                a[3 + k] += x.angular_momentum(i, k) - s[3 + k];
            }
        }
        if (!stepped || !im.kicked[i]) {  // asleep at the kick: its contacts carried the load
            for (int k = 0; k < 3; ++k) {
                a[k] -= h * bd.force(i, k);
                a[3 + k] -= h * bd.torque(i, k);
            }
        }
    }
}

void impulses_sample(const IntervalImpulses& im, i64 sample) {
    for (i64 i = 0; i < im.acc.n0; ++i) {
        double* a = im.acc.row(i);
        double* o = &im.out(sample, i, 0);
        for (int k = 0; k < 6; ++k) {
            o[k] = a[k];
            a[k] = 0.0;
        }
    }
}

}  // namespace step
}  // namespace rb
