// Constraint graph colouring (Box2D v3's constraint_graph.c): the step's active manifolds in
// colours, each colour a set of manifolds that share no dynamic body, and an overflow set for
// the manifolds no colour could take.
//
// Why: inside a colour, solving one manifold changes no body another manifold of the colour
// reads, so the colour's manifolds can be solved in any order, four at a time in the lanes of a
// vector (contact_lanes.hpp) or split over threads, and the result is the same bit for bit. The
// sweep is Gauss-Seidel from colour to colour (colour c sees what colours < c did in this sweep)
// and Jacobi-free inside one (nothing to see). Static geometry and sleeping bodies (the solver's
// static dummy, row N, zero inverse mass) never change, so they do not count: every
// body-on-ground manifold of a pile can share one colour with the others that do not touch it.
//
// Colouring, as Box2D v3 (B2_GRAPH_COLOR_COUNT 24, B2_DYNAMIC_COLOR_COUNT 20): a manifold
// between two dynamic bodies takes the first of the dynamic colours 0..19 that has neither body;
// a manifold between a dynamic body and the static dummy takes the last colour, counting down
// from 22 to 1, that does not have the body (static contacts fill the colours from the other end,
// so that they meet few dynamic ones; Box2D: "higher priority than dyn-dyn constraints"). A
// manifold that finds no colour goes to the overflow set, solved first and one manifold after
// another (Box2D solves its overflow first as well). Box2D keeps colours across steps (a contact
// is coloured when it begins touching); here the colouring is made afresh each step in manifold
// order, which is deterministic and costs one pass over the manifolds with a 32-bit colour set
// per body.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/array.hpp"
#include "engine/manifold.hpp"

namespace rb {

constexpr int GRAPH_COLOURS = 24;                    // Box2D's B2_GRAPH_COLOR_COUNT
constexpr int OVERFLOW_COLOUR = GRAPH_COLOURS - 1;   // B2_OVERFLOW_INDEX
constexpr int DYNAMIC_COLOURS = GRAPH_COLOURS - 4;   // B2_DYNAMIC_COLOR_COUNT

// The step's colouring: order (M_active,) manifold indices, the overflow set first, then each
// non-empty colour from the last (static contacts) to the first (constraint_graph.cpp: why);
// set_start (n_sets + 1,) offsets into order, set 0 the overflow set (possibly
// empty), sets 1.. the colours. Inside a colour the manifolds are sorted by point count, most
// first (stable), so the four lanes of a group mostly have the same count.
struct ConstraintGraph {
    std::vector<i64> order;
    std::vector<i64> set_start;
    std::vector<std::uint32_t> body_colours;  // (N+1,) colours that hold the body (work array)
    std::vector<i64> colour_of;               // (M,) colour of each manifold, -1 inactive (work)
    i64 n_sets() const { return (i64)set_start.size() - 1; }
    i64 n_overflow() const { return set_start[1] - set_start[0]; }
};

// Colour the active manifolds of mi (M, MI_COLS) whose body rows are < n_dyn (dynamic) or
// n_dyn (the static dummy) into g.
void colour_manifolds(V1<ManifoldHead> mi, i64 n_man, i64 n_dyn, ConstraintGraph& g);

}  // namespace rb
