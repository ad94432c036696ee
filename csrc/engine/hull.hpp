// Convex hull shapes of the engine (rblog/engine/hull.py builds them; csrc/engine/hull.cpp holds
// them and their plane collider; the pairs with other shapes are collide_convex's, cylinder.cpp).
//
// A hull body's size row is [id, 0, 0]: id names its Hull in the process's hull table, where
// register_hull put it when the world was built (the same vertices and faces give the same id,
// so building a world again adds nothing). The table only grows and its hulls never move: the
// stages read them from any thread without a lock.
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses
#include <vector>

#include "common/array.hpp"

namespace rb {

struct Hull {
    i64 nv = 0, nf = 0, ne = 0;
    std::vector<double> vert;   // (nv, 3) body frame (centre of mass, principal axes), m
    std::vector<double> fnrm;   // (nf, 3) unit outward face normals, body frame
    std::vector<double> foff;   // (nf,) n . x = foff on the face, m
    std::vector<i64> fstart;    // (nf + 1,) face f's loop is fvert[fstart[f] .. fstart[f + 1])
    std::vector<i64> fvert;     // vertex indices, counter-clockwise about the face's normal
    std::vector<double> edir;   // (ne, 3) unit edge directions, one per class of parallel edges
    // the edges (polytope.hpp: PolytopeView's conventions): (n_edge, 4) rows (v0, v1, f0, f1),
    // v0 -> v1 along face f0's loop, f1 the face across the edge; (n_edge, 3) ecross[k] =
    // fnrm[f1] x fnrm[f0] (the edge's arc on the Gauss map)
    i64 n_edge = 0;
    std::vector<i64> edge;
    std::vector<double> ecross;
    std::vector<double> vert_soa, fnrm_soa, ecross_soa;  // vert, fnrm, ecross by coordinate
    std::vector<i64> fopp;  // (nf,) the face of normal -fnrm[f] exactly, or -1
    std::vector<i64> cstart, cedge;  // the edges by parallel class (polytope.hpp)
    std::vector<double> crep, esign;
    double ext[3] = {0, 0, 0};  // max_v |v_k|: the body-frame box centred on the origin around it
    double radius = 0.0;        // max_v |v| (m)
    i64 max_face = 0;           // the most vertices of a face
};

// The most vertices one face may have (rblog.engine.hull.HULL_MAX_FACE_VERTICES; the test checks
// they agree) and the most hulls a process holds.
constexpr i64 HULL_MAX_FACE_VERTICES = 64;
constexpr i64 MAX_HULLS = 1 << 16;

// Add a hull (or find the same one) and return its id; throws rb::Error on malformed arrays.
i64 register_hull(V2<double> vert, V2<double> fnrm, V1<double> foff, V1<i64> fstart,
                  V1<i64> fvert);
// The hull of a size row ([id, 0, 0]); id must come from register_hull.
const Hull& hull_of(const double* size);
i64 hull_count();

}  // namespace rb
