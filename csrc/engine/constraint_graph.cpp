// The colour stage of the contact step (constraint_graph.hpp holds the why and the rules).
#include <algorithm>

#include "engine/constraint_graph.hpp"
#include "engine/manifold.hpp"

namespace rb {

void colour_manifolds(V1<ManifoldHead> mi, i64 n_man, i64 n_dyn, ConstraintGraph& g) {
    g.body_colours.assign(n_dyn + 1, 0u);
    g.colour_of.assign(n_man, -1);
    i64 count[GRAPH_COLOURS] = {0};
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi[m].active) continue;
        i64 a = mi[m].a, b = mi[m].b;
        bool dyn_a = a < n_dyn, dyn_b = b < n_dyn;
        int c = OVERFLOW_COLOUR;
        if (dyn_a && dyn_b) {
            std::uint32_t used = g.body_colours[a] | g.body_colours[b];
            for (int k = 0; k < DYNAMIC_COLOURS; ++k) {
                if (!(used >> k & 1u)) {
                    c = k;
                    break;
                }
            }
            if (c != OVERFLOW_COLOUR) {
                g.body_colours[a] |= 1u << c;
                g.body_colours[b] |= 1u << c;
            }
        } else if (dyn_a || dyn_b) {
            i64 d = dyn_a ? a : b;
            std::uint32_t used = g.body_colours[d];
            for (int k = OVERFLOW_COLOUR - 1; k >= 1; --k) {
                if (!(used >> k & 1u)) {
                    c = k;
                    break;
                }
            }
            if (c != OVERFLOW_COLOUR) g.body_colours[d] |= 1u << c;
        }
        // (a manifold with no dynamic body is never active; were it, overflow solves it alone)
        g.colour_of[m] = c;
        count[c] += 1;
    }
    // sets: overflow first, then the non-empty colours from the last to the first, so that a
    // sweep meets the static contacts (colours 22 down) before the dynamic ones (0 up): the
    // ground carries a pile, and a sweep that settles the ground contacts first passes the load
    // up the pile in the same sweep. Measured on the 500-box loose pile (bench_pile's scene, 2 s,
    // one thread, CPU time): 203-213 steps/s with 390 bodies awake at the end, against 192-195
    // steps/s and 448 awake with the colours in increasing order (main's manifold order: 167-181
    // steps/s, 334 awake)
    g.set_start.clear();
    g.set_start.push_back(0);
    i64 at = count[OVERFLOW_COLOUR];
    g.set_start.push_back(at);
    i64 first[GRAPH_COLOURS];
    first[OVERFLOW_COLOUR] = 0;
    for (int k = OVERFLOW_COLOUR - 1; k >= 0; --k) {
        if (count[k] == 0) {
            first[k] = -1;
            continue;
        }
        first[k] = at;
        at += count[k];
        g.set_start.push_back(at);
    }
    g.order.resize(at);
    i64 fill[GRAPH_COLOURS];
    for (int k = 0; k < GRAPH_COLOURS; ++k) fill[k] = first[k];
    for (i64 m = 0; m < n_man; ++m) {
        int c = (int)g.colour_of[m];
        if (c < 0) continue;
        g.order[fill[c]++] = m;
    }
    // inside a colour: most points first (the lanes of a group then share their point count);
    // the overflow set keeps manifold order (it is solved one manifold after another)
    for (i64 s = 1; s < g.n_sets(); ++s)
        std::stable_sort(g.order.begin() + g.set_start[s], g.order.begin() + g.set_start[s + 1],
                         [&](i64 x, i64 y) { return mi[x].count > mi[y].count; });
}

}  // namespace rb
