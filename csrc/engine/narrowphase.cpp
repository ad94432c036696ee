// Narrowphase: contact manifolds of a pair of shapes, through a table keyed by the shape pair
// (rblog/engine/contact/narrowphase.py keeps the registry, the names and the docs; the colliders
// are here, the same formulas in the same order).
//
// Conventions (rblog.contract.trajectory.Contacts uses the same ones):
//
// * A collider collide_X_Y(shape X = "a", shape Y = "b", ...) returns a manifold of up to four
//   points sharing one normal, a unit world vector pointing FROM b INTO a (the direction in which
//   a must move to separate).
// * sep is the signed gap along the normal (m): > 0 apart, < 0 penetration. Points are kept while
//   the gap is below spec (speculative contacts), so a point can have separation > 0.
// * a point is the midpoint between the two surfaces (Box2D's convention), world frame.
// * fid is a feature id (which vertex, edge or clip produced the point) used to carry the
//   solver's impulses from one step to the next (warm starting).
//
// Dispatch: geometry codes GEOM_SPHERE, GEOM_BOX (dynamic or static boxes), GEOM_CAPSULE,
// GEOM_CYLINDER, GEOM_HULL, GEOM_PLANE (the ground). NARROWPHASE_TABLE[lower code][higher code] is the collider; the pair is swapped (and
// the normal negated) when the lower code is on body b. A pair with no entry is refused when the
// world is built (UnsupportedShapePair, Python), never silently skipped; collide() returns -1.
//
// Box-box lives in box_box.cpp (separating axes, clipping, reduction), the capsule pairs in
// capsule.cpp, the cylinder pairs in cylinder.cpp, hull - plane in hull.cpp, box - hull and
// hull - hull in polytope.cpp (every other hull pair is cylinder.cpp's collide_convex).
#include <algorithm>
#include <cmath>

#include "common/errors.hpp"
#include "engine/collision.hpp"
#include "engine/hull.hpp"
#include "engine/polytope.hpp"

namespace rb {

CollisionConstants& collision_constants() {
    static CollisionConstants c;
    return c;
}

void require_collision_constants() {
    if (!collision_constants().set)
        throw Error("RblogError",
                    "the collision constants were never set: import "
                    "rblog.engine.contact.narrowphase before calling the contact core");
}

// ---- colliders ------------------------------------------------------------------------------

// Sphere a (centre ca, radius ra) vs sphere b. One point on the line of centres.
i64 collide_sphere_sphere(const double* ca, double ra, const double* cb, double r_b, double spec,
                          double* nrm, Pts pts, double* sep, i64* fid) {
    double dx = ca[0] - cb[0], dy = ca[1] - cb[1], dz = ca[2] - cb[2];
    double d2 = dx * dx + dy * dy + dz * dz;
    double rr = ra + r_b;
    if (d2 > (rr + spec) * (rr + spec)) return 0;
    double d = std::sqrt(d2);
    double nx, ny, nz;
    if (d > 1e-12 * rr) {
        nx = dx / d;
        ny = dy / d;
        nz = dz / d;
    } else {  // concentric: any direction will do
        nx = 0.0;
        ny = 0.0;
        nz = 1.0;
    }
    double s = d - rr;
    nrm[0] = nx;
    nrm[1] = ny;
    nrm[2] = nz;
    // midpoint between the surfaces: b's surface point plus half the gap
    double k = r_b + 0.5 * s;
    pts[0][0] = cb[0] + k * nx;
    pts[0][1] = cb[1] + k * ny;
    pts[0][2] = cb[2] + k * nz;
    sep[0] = s;
    fid[0] = 0;
    return 1;
}

// Sphere a vs box b (centre cb, rotation rotb body -> world, half extents eb).
i64 collide_sphere_box(const double* ca, double ra, const double* cb, M3 rotb, const double* eb,
                       double spec, double* nrm, Pts pts, double* sep, i64* fid) {
    double dx = ca[0] - cb[0], dy = ca[1] - cb[1], dz = ca[2] - cb[2];
    // sphere centre in the box frame
    double lx = rotb(0, 0) * dx + rotb(1, 0) * dy + rotb(2, 0) * dz;
    double ly = rotb(0, 1) * dx + rotb(1, 1) * dy + rotb(2, 1) * dz;
    double lz = rotb(0, 2) * dx + rotb(1, 2) * dy + rotb(2, 2) * dz;
    double qx = std::min(std::max(lx, -eb[0]), eb[0]);
    double qy = std::min(std::max(ly, -eb[1]), eb[1]);
    double qz = std::min(std::max(lz, -eb[2]), eb[2]);
    double ox = lx - qx, oy = ly - qy, oz = lz - qz;
    double o2 = ox * ox + oy * oy + oz * oz;
    double s, nlx, nly, nlz;
    if (o2 > 0.0) {
        // centre outside the box: closest point q on the surface
        double d = std::sqrt(o2);
        s = d - ra;
        if (s > spec) return 0;
        nlx = ox / d;
        nly = oy / d;
        nlz = oz / d;
    } else {
        // centre inside: leave through the nearest face
        double gx = eb[0] - std::fabs(lx), gy = eb[1] - std::fabs(ly), gz = eb[2] - std::fabs(lz);
        nlx = 0.0;
        nly = 0.0;
        nlz = 0.0;
        if (gx <= gy && gx <= gz) {
            nlx = lx >= 0.0 ? 1.0 : -1.0;
            qx = nlx * eb[0];
            s = -gx - ra;
        } else if (gy <= gz) {
            nly = ly >= 0.0 ? 1.0 : -1.0;
            qy = nly * eb[1];
            s = -gy - ra;
        } else {
            nlz = lz >= 0.0 ? 1.0 : -1.0;
            qz = nlz * eb[2];
            s = -gz - ra;
        }
    }
    double nx = rotb(0, 0) * nlx + rotb(0, 1) * nly + rotb(0, 2) * nlz;
    double ny = rotb(1, 0) * nlx + rotb(1, 1) * nly + rotb(1, 2) * nlz;
    double nz = rotb(2, 0) * nlx + rotb(2, 1) * nly + rotb(2, 2) * nlz;
    double px = cb[0] + rotb(0, 0) * qx + rotb(0, 1) * qy + rotb(0, 2) * qz;
    double py = cb[1] + rotb(1, 0) * qx + rotb(1, 1) * qy + rotb(1, 2) * qz;
    double pz = cb[2] + rotb(2, 0) * qx + rotb(2, 1) * qy + rotb(2, 2) * qz;
    nrm[0] = nx;
    nrm[1] = ny;
    nrm[2] = nz;
    pts[0][0] = px + 0.5 * s * nx;
    pts[0][1] = py + 0.5 * s * ny;
    pts[0][2] = pz + 0.5 * s * nz;
    sep[0] = s;
    fid[0] = 0;
    return 1;
}

// Sphere a vs the plane dot(pn, x) = poff (b); the normal is the plane's.
i64 collide_sphere_plane(const double* ca, double ra, const double* pn, double poff, double spec,
                         double* nrm, Pts pts, double* sep, i64* fid) {
    double s = pn[0] * ca[0] + pn[1] * ca[1] + pn[2] * ca[2] - poff - ra;
    if (s > spec) return 0;
    nrm[0] = pn[0];
    nrm[1] = pn[1];
    nrm[2] = pn[2];
    double k = ra + 0.5 * s;
    pts[0][0] = ca[0] - k * pn[0];
    pts[0][1] = ca[1] - k * pn[1];
    pts[0][2] = ca[2] - k * pn[2];
    sep[0] = s;
    fid[0] = 0;
    return 1;
}

// Box a vs the plane dot(pn, x) = poff: the (up to four deepest) vertices within spec.
i64 collide_box_plane(const double* ca, M3 rota, const double* ea, const double* pn, double poff,
                      double spec, double* nrm, Pts pts, double* sep, i64* fid) {
    // plane normal in the box frame, and the centre's height
    double nlx = rota(0, 0) * pn[0] + rota(1, 0) * pn[1] + rota(2, 0) * pn[2];
    double nly = rota(0, 1) * pn[0] + rota(1, 1) * pn[1] + rota(2, 1) * pn[2];
    double nlz = rota(0, 2) * pn[0] + rota(1, 2) * pn[1] + rota(2, 2) * pn[2];
    double hc = pn[0] * ca[0] + pn[1] * ca[1] + pn[2] * ca[2] - poff;
    // quick reject on the support distance
    if (hc - (std::fabs(nlx) * ea[0] + std::fabs(nly) * ea[1] + std::fabs(nlz) * ea[2]) > spec)
        return 0;
    i64 count = 0;
    for (i64 k = 0; k < 8; ++k) {
        double sx = (k & 1) ? ea[0] : -ea[0];
        double sy = (k & 2) ? ea[1] : -ea[1];
        double sz = (k & 4) ? ea[2] : -ea[2];
        double s = hc + nlx * sx + nly * sy + nlz * sz;
        if (s > spec) continue;
        double vx = ca[0] + rota(0, 0) * sx + rota(0, 1) * sy + rota(0, 2) * sz;
        double vy = ca[1] + rota(1, 0) * sx + rota(1, 1) * sy + rota(1, 2) * sz;
        double vz = ca[2] + rota(2, 0) * sx + rota(2, 1) * sy + rota(2, 2) * sz;
        pts[count][0] = vx - 0.5 * s * pn[0];
        pts[count][1] = vy - 0.5 * s * pn[1];
        pts[count][2] = vz - 0.5 * s * pn[2];
        sep[count] = s;
        fid[count] = k;
        count += 1;
    }
    nrm[0] = pn[0];
    nrm[1] = pn[1];
    nrm[2] = pn[2];
    if (count > MAX_MANIFOLD_POINTS) {
        // keep the four deepest (a box within spec of a plane on more than four vertices is
        // thinner than spec; its lower face is what matters)
        for (i64 i = 0; i < MAX_MANIFOLD_POINTS; ++i) {
            i64 best = i;
            for (i64 j = i + 1; j < count; ++j)
                if (sep[j] < sep[best]) best = j;
            swap_point(pts, sep, fid, i, best);
        }
        count = MAX_MANIFOLD_POINTS;
    }
    return count;
}

// ---- the table ------------------------------------------------------------------------------
// One signature for every entry: (a, b) shape data, the plane's (pn, poff), spec, buffers.

static i64 entry_sphere_sphere(const double* ca, M3, const double* sa, const double* cb, M3,
                               const double* sb, const double*, double, double spec,
                               ColliderBuffers& b) {
    return collide_sphere_sphere(ca, sa[0], cb, sb[0], spec, b.nrm, b.pts, b.sep, b.fid);
}
static i64 entry_sphere_box(const double* ca, M3, const double* sa, const double* cb, M3 rotb,
                            const double* sb, const double*, double, double spec,
                            ColliderBuffers& b) {
    return collide_sphere_box(ca, sa[0], cb, rotb, sb, spec, b.nrm, b.pts, b.sep, b.fid);
}
static i64 entry_box_box(const double* ca, M3 rota, const double* sa, const double* cb, M3 rotb,
                         const double* sb, const double*, double, double spec,
                         ColliderBuffers& b) {
    return collide_box_box(ca, rota, sa, cb, rotb, sb, spec, b.nrm, b.pts, b.sep, b.fid, b.work,
                           b.poly);
}
static i64 entry_sphere_plane(const double* ca, M3, const double* sa, const double*, M3,
                              const double*, const double* pn, double poff, double spec,
                              ColliderBuffers& b) {
    return collide_sphere_plane(ca, sa[0], pn, poff, spec, b.nrm, b.pts, b.sep, b.fid);
}
static i64 entry_box_plane(const double* ca, M3 rota, const double* sa, const double*, M3,
                           const double*, const double* pn, double poff, double spec,
                           ColliderBuffers& b) {
    return collide_box_plane(ca, rota, sa, pn, poff, spec, b.nrm, b.pts, b.sep, b.fid);
}

static i64 entry_sphere_capsule(const double* ca, M3, const double* sa, const double* cb,
                                M3 rotb, const double* sb, const double*, double, double spec,
                                ColliderBuffers& b) {
    return collide_sphere_capsule(ca, sa[0], cb, rotb, sb, spec, b.nrm, b.pts, b.sep, b.fid);
}
// box a, capsule b: the capsule's collider as (capsule, box), its normal negated
static i64 entry_box_capsule(const double* ca, M3 rota, const double* sa, const double* cb,
                             M3 rotb, const double* sb, const double*, double, double spec,
                             ColliderBuffers& b) {
    i64 n = collide_capsule_box(cb, rotb, sb, ca, rota, sa, spec, b.nrm, b.pts, b.sep, b.fid);
    for (int k = 0; k < 3; ++k) b.nrm[k] = -b.nrm[k];
    return n;
}
static i64 entry_capsule_capsule(const double* ca, M3 rota, const double* sa, const double* cb,
                                 M3 rotb, const double* sb, const double*, double, double spec,
                                 ColliderBuffers& b) {
    return collide_capsule_capsule(ca, rota, sa, cb, rotb, sb, spec, b.nrm, b.pts, b.sep, b.fid);
}
static i64 entry_capsule_plane(const double* ca, M3 rota, const double* sa, const double*, M3,
                               const double*, const double* pn, double poff, double spec,
                               ColliderBuffers& b) {
    return collide_capsule_plane(ca, rota, sa, pn, poff, spec, b.nrm, b.pts, b.sep, b.fid);
}

static i64 entry_sphere_cylinder(const double* ca, M3, const double* sa, const double* cb,
                                 M3 rotb, const double* sb, const double*, double, double spec,
                                 ColliderBuffers& b) {
    return collide_sphere_cylinder(ca, sa[0], cb, rotb, sb, spec, b.nrm, b.pts, b.sep, b.fid);
}
static i64 entry_box_cylinder(const double* ca, M3 rota, const double* sa, const double* cb,
                              M3 rotb, const double* sb, const double*, double, double spec,
                              ColliderBuffers& b) {
    return collide_convex(GEOM_BOX, ca, rota, sa, GEOM_CYLINDER, cb, rotb, sb, spec, b.nrm, b.pts,
                          b.sep, b.fid);
}
static i64 entry_capsule_cylinder(const double* ca, M3 rota, const double* sa, const double* cb,
                                  M3 rotb, const double* sb, const double*, double, double spec,
                                  ColliderBuffers& b) {
    return collide_convex(GEOM_CAPSULE, ca, rota, sa, GEOM_CYLINDER, cb, rotb, sb, spec, b.nrm,
                          b.pts, b.sep, b.fid);
}
static i64 entry_cylinder_cylinder(const double* ca, M3 rota, const double* sa, const double* cb,
                                   M3 rotb, const double* sb, const double*, double, double spec,
                                   ColliderBuffers& b) {
    return collide_convex(GEOM_CYLINDER, ca, rota, sa, GEOM_CYLINDER, cb, rotb, sb, spec, b.nrm,
                          b.pts, b.sep, b.fid);
}
static i64 entry_cylinder_plane(const double* ca, M3 rota, const double* sa, const double*, M3,
                                const double*, const double* pn, double poff, double spec,
                                ColliderBuffers& b) {
    return collide_cylinder_plane(ca, rota, sa, pn, poff, spec, b.nrm, b.pts, b.sep, b.fid);
}

static i64 entry_hull_plane(const double* ca, M3 rota, const double* sa, const double*, M3,
                            const double*, const double* pn, double poff, double spec,
                            ColliderBuffers& b) {
    return collide_hull_plane(ca, rota, sa, pn, poff, spec, b.nrm, b.pts, b.sep, b.fid);
}
// box - hull and hull - hull: separating axes and clipping (polytope.cpp)
static i64 entry_box_hull(const double* ca, M3 rota, const double* sa, const double* cb, M3 rotb,
                          const double* sb, const double*, double, double spec,
                          ColliderBuffers& b) {
    double vert[48], foff[6];
    return collide_polytopes(box_view(sa, vert, foff), ca, rota, hull_view(hull_of(sb)), cb, rotb,
                             spec, b.nrm, b.pts, b.sep, b.fid);
}
static i64 entry_hull_hull(const double* ca, M3 rota, const double* sa, const double* cb,
                           M3 rotb, const double* sb, const double*, double, double spec,
                           ColliderBuffers& b) {
    return collide_polytopes(hull_view(hull_of(sa)), ca, rota, hull_view(hull_of(sb)), cb, rotb,
                             spec, b.nrm, b.pts, b.sep, b.fid);
}
// (X, hull): collide_convex on the pair as it comes (X the lower code)
template <i64 GA>
static i64 entry_x_hull(const double* ca, M3 rota, const double* sa, const double* cb, M3 rotb,
                        const double* sb, const double*, double, double spec,
                        ColliderBuffers& b) {
    return collide_convex(GA, ca, rota, sa, GEOM_HULL, cb, rotb, sb, spec, b.nrm, b.pts, b.sep,
                          b.fid);
}

// NARROWPHASE_TABLE: [lower geometry code][higher code] (narrowphase.py's NARROWPHASE_TABLE has
// the same keys; tests/engine/contact/test_collision_core.py checks it)
static const ColliderFn NARROWPHASE_TABLE[N_GEOM][N_GEOM] = {
    //             sphere               box               capsule               cylinder               hull                             plane
    /* sphere   */ {entry_sphere_sphere, entry_sphere_box, entry_sphere_capsule, entry_sphere_cylinder, entry_x_hull<GEOM_SPHERE>,   entry_sphere_plane},
    /* box      */ {nullptr, entry_box_box, entry_box_capsule, entry_box_cylinder, entry_box_hull, entry_box_plane},
    /* capsule  */ {nullptr, nullptr, entry_capsule_capsule, entry_capsule_cylinder, entry_x_hull<GEOM_CAPSULE>, entry_capsule_plane},
    /* cylinder */ {nullptr, nullptr, nullptr, entry_cylinder_cylinder, entry_x_hull<GEOM_CYLINDER>, entry_cylinder_plane},
    /* hull     */ {nullptr, nullptr, nullptr, nullptr, entry_hull_hull, entry_hull_plane},
    /* plane    */ {nullptr, nullptr, nullptr, nullptr, nullptr, nullptr},
};

ColliderFn narrowphase_fn(i64 geom_lo, i64 geom_hi) {
    if (geom_lo < 0 || geom_hi < geom_lo || geom_hi >= N_GEOM) return nullptr;
    return NARROWPHASE_TABLE[geom_lo][geom_hi];
}

// parted_along: whether collide() at speculative distance spec provably returns no point, from
// the gap g(u) of one axis u (collision.hpp convex_axis_gap), without running the collider.
//
// Proof. Let D be the pair's signed distance and D_c = D + r_a + r_b that of its cores (radii
// r: a sphere's or capsule's, else 0). g(u) <= D for every unit u (the separating-axis theorem,
// apart or overlapping), so g(u) > spec + PARTED_MARGIN_M gives D_c > spec + r_a + r_b +
// PARTED_MARGIN_M. The colliders below return no point when the core gap c they compute
// satisfies c - r_a - r_b > spec, and each c is at least D_c, less round-off:
// * collide_convex: c is convex_distance's sep (csrc/common/convex.hpp). Apart, it is |v| for a
//   point v of the Minkowski difference (GJK's simplex lies in it): >= D_c. Overlapping, it is
//   -d for the nearest face (distance d) of EPA's polytope, whose vertices are points of the
//   difference, so the polytope lies inside it: with the origin inside the polytope, d is at
//   most the depth, -d >= D_c; a stalled GJK keeps EPA's answer with the origin outside only
//   when d u lies in the nearest face (a point of the difference at distance -d: -d >= D_c),
//   else its own |v|; a flat difference or no face: 0, with the origin on it (D_c <= 0). The
//   origin is taken as on GJK's simplex when |v| <= 1e-14 of the difference's extent, which
//   moves every case above by at most that much.
// * capsule - box: c is the distance of an actual point of the segment (segment_box_closest's
//   least over its candidates) from the box: >= D_c, when c > 1e-12 of the pair's size (below,
//   the collider takes the segment as meeting the box); so the pair also needs g(u) + r_capsule
//   > PARTED_MARGIN_M, which is above that.
// The round-off of g(u), of GJK's and EPA's sums and of the 1e-14 extent are below 1e-12 m for
// shapes and coordinates below 1e2 m, and PARTED_MARGIN_M is 1e3 times that: c - r_a - r_b >=
// D - 1e-12 m > spec, so the collider would have returned 0. Any u will do (a poor one only
// fails the test); a caller passes the pair's last normal.
constexpr double PARTED_MARGIN_M = 1e-9;

bool parted_along(i64 ga, i64 gb, const double* ca, M3 rota, const double* sa, const double* cb,
                  M3 rotb, const double* sb, const double* u, double spec) {
    if (!axis_parts(ga, gb)) return false;
    const bool capsule_box = std::min(ga, gb) == GEOM_BOX;
    const double g = convex_axis_gap(ga, ca, rota, sa, gb, cb, rotb, sb, u);
    if (!(g > spec + PARTED_MARGIN_M)) return false;
    if (capsule_box) return g + (ga == GEOM_CAPSULE ? sa[0] : sb[0]) > PARTED_MARGIN_M;
    return true;
}

i64 collide(i64 ga, i64 gb, const double* ca, M3 rota, const double* sa, const double* cb,
            M3 rotb, const double* sb, const double* pn, double poff, double spec,
            ColliderBuffers& buf) {
    const bool swap = ga > gb;
    ColliderFn fn = swap ? narrowphase_fn(gb, ga) : narrowphase_fn(ga, gb);
    if (fn == nullptr) return -1;  // no collider: the world checks the table up front: a bug
    // a plane is always b (the highest code, the highest shape id): never swapped
    i64 n = swap ? fn(cb, rotb, sb, ca, rota, sa, pn, poff, spec, buf)
                 : fn(ca, rota, sa, cb, rotb, sb, pn, poff, spec, buf);
    if (swap && n > 0)
        for (int k = 0; k < 6; ++k) buf.nrm[k] = -buf.nrm[k];
    return n;
}

}  // namespace rb
