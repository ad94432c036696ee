// Polytope - polytope contact: hull - hull and box - hull (polytope.cpp; narrowphase.cpp's table
// calls it, its conventions: normal from b into a, sep < 0 penetration, points midway between
// the surfaces, feature ids for warm starting).
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses
#include <vector>

#include "common/array.hpp"
#include "engine/collision.hpp"
#include "engine/hull.hpp"

namespace rb {

// A convex polytope in its own frame: a hull's arrays (hull.hpp) or a box's (box_view).
//   vert (nv, 3); fnrm (nf, 3) unit outward normals, foff (nf,): n . x = foff on face f;
//   face f's loop fvert[fstart[f] .. fstart[f + 1]), counter-clockwise about its normal;
//   edge (ne, 4) rows (v0, v1, f0, f1): v0 -> v1 along f0's loop, f1 the face across it;
//   ecross (ne, 3) = fnrm[f1] x fnrm[f0], the edge's arc on the Gauss map (along v0 -> v1's
//   opposite, of length sin of the dihedral angle's supplement).
struct PolytopeView {
    i64 nv, nf, ne;
    const double* vert;
    const double* fnrm;
    const double* foff;
    const i64* fstart;
    const i64* fvert;
    const i64* edge;
    const double* ecross;
    double radius;  // max_v |v| (m)
    double ext[3];  // max_v |v_k|: the box centred on the origin around it (m)
    // vert, fnrm and ecross by coordinate: (3, nv), (3, nf), (3, ne) (loops over them vectorize)
    const double* vert_soa;
    const double* fnrm_soa;
    const double* ecross_soa;
    const i64* fopp;  // (nf,) the face whose normal is exactly -fnrm[f], or -1
    // the edges by class of parallel ones: class k's edges cedge[cstart[k] .. cstart[k + 1]),
    // its direction crep[k] (3; its first edge's ecross), esign[e] = +-1: ecross[e] along
    // +-crep of its class
    i64 nc;
    const i64* cstart;
    const i64* cedge;
    const double* crep;
    const double* esign;
};

// The edges of a closed polytope from its face loops (each edge once, as f0's loop runs it; an
// edge without a twin face is left out): appends rows (v0, v1, f0, f1) to edge and
// fnrm[f1] x fnrm[f0] to ecross.
void polytope_edges(i64 nf, const i64* fstart, const i64* fvert, const double* fnrm,
                    std::vector<i64>& edge, std::vector<double>& ecross);
// (nf,) the face whose normal is exactly (bit for bit) the negated normal of face f, or -1.
std::vector<i64> opposite_faces(i64 nf, const double* fnrm);
// The edge classes of a polytope (PolytopeView's cstart, cedge, crep, esign) from ecross
// (ne, 3): edges whose arcs lie on one great circle (ecross parallel to sin 1e-9) share one.
struct EdgeClasses {
    std::vector<i64> cstart, cedge;
    std::vector<double> crep, esign;
};
EdgeClasses edge_classes(const std::vector<double>& ecross);
// (n, 3) rows as (3, n) columns.
std::vector<double> by_coordinate(const std::vector<double>& rows);

// Contact of polytope a (centre ca, rotation rota body -> world) and polytope b: separating axes
// (both polytopes' face normals, the edge pairs whose arcs cross on the Gauss map), a clipped
// face manifold or one edge-edge point (polytope.cpp's derivation). Returns n1 + 8 n2 (a second,
// face manifold in rows 4.. with its normal in nrm[3:6], as box - box).
i64 collide_polytopes(const PolytopeView& A, const double* ca, M3 rota, const PolytopeView& B,
                      const double* cb, M3 rotb, double spec, double* nrm, Pts pts, double* sep,
                      i64* fid);

// A box of half extents e as a polytope: vertex k at ((k & 1) ? +e0 : -e0, (k & 2) ..,
// (k & 4) ..) (collide_box_plane's vertex ids), face 2 axis + (1 on the + side). vert (48:
// by vertex, then by coordinate) and foff (6) are the caller's room.
PolytopeView box_view(const double* e, double* vert, double* foff);
// A hull as a polytope (its arrays, not copied).
PolytopeView hull_view(const Hull& h);

}  // namespace rb
